"""The dc-lesson command: every study of the book, from the command line.

  dc-lesson tour                        the ten tasks (frames, sizes, random returns),
                                        then BC, GAIL and DC on reacher4: the headline
  dc-lesson tasks                       the table of task sizes and horizons
  dc-lesson expert train --task NAME    train (or resume) the PPO expert of NAME
                                        (a planner expert: write its settings)
  dc-lesson expert eval --task NAME     measure the expert of NAME (--episodes N)
  dc-lesson expert dagger --task NAME   DAgger from NAME's planner (humanoid; --hours)
  dc-lesson demos --task NAME           roll out the expert of NAME into data/demos/
  dc-lesson train LEARNER --task NAME   train one learner (bc, ppo, gail, dc, dril, pwil,
                                        ndi, gpril) at the budget and evaluate it; --steps
                                        sets its interactions, --save writes its policy
  dc-lesson perf WHAT                   speed benchmarks (dc-lesson perf -h lists them)
  dc-lesson sweep STUDY [--dry-run]     a study's cells on Ray (resumable, accumulating);
                                        STUDY all: every study (--dry-run: the ledger);
                                        --recheck N: rerun N finished cells, compare
  dc-lesson aggregate STUDY             its cells -> data/results/STUDY.json (intervals)
  dc-lesson seal-cells                  add digests to cell records made before they had them

Sizes follow the budget: set DC_LESSON_BUDGET to smoke (seconds, numbers mean nothing),
lesson (the default, minutes) or paper (the paper's sizes, hours). A wrong value, a missing
or damaged file, or an output that cannot be written stops the command before any compute
with one line saying what is wrong and how to fix it, and exit status 2.
"""

from __future__ import annotations

import argparse
import os
import sys

from dc_lesson.cli._args import Parser, UsageError, positive_float, positive_int, seed_int
from dc_lesson.cli.run import (LEARNERS, PERFS, cmd_demos, cmd_expert, cmd_perf, cmd_tasks,
                               cmd_tour, cmd_train)
from dc_lesson.cli.sweeps import cmd_aggregate, cmd_seal_cells, cmd_sweep


# -- the parser ---------------------------------------------------------------------------------

def _choices_help(table: dict) -> str:
    width = max(map(len, table)) + 2
    return "\n".join(f"  {name:<{width}}{text}" for name, (text, _) in table.items())


def build_parser() -> argparse.ArgumentParser:
    raw = argparse.RawDescriptionHelpFormatter
    p = Parser(prog="dc-lesson", description=__doc__, formatter_class=raw)
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")
    s = sub.add_parser("tasks", help="the table of task sizes and horizons")
    s.set_defaults(func=cmd_tasks)
    s = sub.add_parser("tour", help="the ten tasks, then BC, GAIL and DC on reacher4")
    s.add_argument("--out", default="outputs", help="folder for the figures (default: outputs)")
    s.add_argument("--seed", type=seed_int, default=0,
                   help="seed of the random episodes and of the headline's runs (default: 0)")
    s.add_argument("--save", default=None, help="also write the random returns to this JSON file")
    s.add_argument("--no-headline", action="store_true",
                   help="skip the closing BC / GAIL / DC comparison on reacher4")
    s.set_defaults(func=cmd_tour)
    s = sub.add_parser("demos", help="roll out a task's expert into data/demos/")
    s.add_argument("--task", nargs="+", required=True, help="one or more task names")
    s.add_argument("--stage", choices=["demos", "eval"], default=None,
                   help="planner experts only (--variant planner of ant, walker, humanoid): "
                        "collect only this "
                        "stage's episodes; run the two stages as two processes side by side, "
                        "then once without --stage to combine them")
    s.add_argument("--first", type=positive_int, default=None,
                   help="with --stage eval: collect that stage's episodes from this one on, "
                        "in a file of their own (a second eval process takes the end)")
    s.add_argument("--threads", type=positive_int, default=None,
                   help="planner experts: mujoco.rollout threads (results do not depend on it)")
    s.add_argument("--variant", default=None,
                   help="another expert of the task: 'coin' (reacher2, reacher4, halfcheetah2: "
                        "the mode drawn by a hidden coin per episode), 'planner' (walker, "
                        "ant, humanoid: the sampling planner, minutes per episode)")
    s.set_defaults(func=cmd_demos)
    s = sub.add_parser("expert", help="train or evaluate a task's expert",
                       description="expert train: train (or resume from its checkpoint) the PPO "
                                   "expert of a task, then evaluate it.\nexpert eval: "
                                   "evaluate the expert of a task.", formatter_class=raw)
    s.add_argument("what", choices=["train", "eval", "dagger"],
                   help="train, eval, or dagger (a network expert distilled from the planner "
                        "by DAgger: humanoid)")
    s.add_argument("--task", nargs="+", required=True, help="one or more task names")
    s.add_argument("--steps", type=positive_int, default=None,
                   help="train: total environment steps instead of the recipe's")
    s.add_argument("--restart", action="store_true",
                   help="train: discard the checkpoint (even a committed one made with another "
                        "configuration) and train from the first update")
    s.add_argument("--hours", type=positive_float, default=None,
                   help="train, network experts (walker, ant, humanoid): stop SAC at its first "
                        "checkpoint after this many hours; dagger: after the first round past "
                        "them; run again to resume")
    s.add_argument("--episodes", type=positive_int, default=10,
                   help="evaluation episodes (default: 10)")
    s.set_defaults(func=cmd_expert)
    s = sub.add_parser("train", help=f"train one learner ({', '.join(LEARNERS)}) on a task")
    s.add_argument("learner", help=", ".join(LEARNERS) + " (the registry, "
                   "dc_lesson.algorithms.ALGORITHMS)")
    s.add_argument("--task", nargs="+", required=True, help="one or more task names")
    s.add_argument("--demos", type=positive_int, default=None,
                   help="demonstrations to learn from (default: the budget's il_demos)")
    s.add_argument("--seed", type=seed_int, default=0, help="the run's seed (default: 0)")
    s.add_argument("--steps", type=positive_int, default=None,
                   help="environment interactions after the warm start (default: the "
                        "budget's il_steps); not for bc, which learns from demonstrations alone")
    s.add_argument("--save", default=None,
                   help="write the policy here; {task} and {learner} are filled in")
    s.set_defaults(func=cmd_train)
    s = sub.add_parser("perf", help="speed benchmarks (ratios, no science)",
                       description="Speed benchmarks:\n" + _choices_help(PERFS),
                       formatter_class=raw)
    s.add_argument("what", choices=list(PERFS), metavar="WHAT", help=", ".join(PERFS))
    s.add_argument("--tasks", nargs="*", default=None, help="rollout: task names (default: all)")
    s.add_argument("--steps", type=positive_int, default=None,
                   help="rollout: control steps per task (default: the budget's bench_steps)")
    s.add_argument("--out", default=None, help="also write the figures to this JSON file")
    s.add_argument("--learners", nargs="*", default=None,
                   help="learners: which learners (default: bc ppo gail dc)")
    s.add_argument("--repeats", type=positive_int, default=2,
                   help="learners: timed runs per path (default 2)")
    s.add_argument("--seeds", type=positive_int, default=None,
                   help="dc-fit: seeds, each a BC start and two DC runs (default 5)")
    s.add_argument("--variant", default=None, choices=["fit", "fit+reward", "defaults"],
                   help="dc-fit: what to compare with the stored runs' numerics: the cheaper "
                        "training solver, and the reward's, or today's defaults (default: "
                        "fit)")
    s.add_argument("--before", default=None, metavar="REVISION",
                   help="runs: the earlier revision to time against today's (default: "
                        "7445a95, where issue 14 began)")
    s.set_defaults(func=cmd_perf)
    s = sub.add_parser("sweep", help="run a study's cells on Ray (skips finished cells)")
    s.add_argument("study", help="a study of dc_lesson.experiments.studies (bc_demos, ...), "
                   "or all (every study in turn; with --dry-run the whole grid's ledger)")
    s.add_argument("--budget", default=None, help="smoke | lesson | paper (default: "
                   "DC_LESSON_BUDGET)")
    s.add_argument("--only", nargs="+", default=(), metavar="KEY=VALUE",
                   help="keep matching cells: task=reacher4 seed=0,1 learner=bc n_demos=4")
    s.add_argument("--dry-run", action="store_true", help="list the cells and their cost")
    s.add_argument("--address", default=None, help="join this Ray cluster (e.g. auto)")
    s.add_argument("--cpus", type=positive_int, default=None, help="local Ray workers "
                   "(default: all cores)")
    s.add_argument("--hours", type=positive_float, default=None,
                   help="start only the cells whose estimated cost ends within this many "
                        "hours; running cells finish (a session's length)")
    s.add_argument("--priced-since", default=None, metavar="ISO_TIME",
                   help="with --dry-run: also price the whole grid by the cells finished "
                        "since this time (UTC), e.g. a session that gave the machine to the "
                        "sweep alone")
    s.add_argument("--priced-until", default=None, metavar="ISO_TIME",
                   help="with --priced-since: only the cells finished before this time (the "
                        "end of that session)")
    s.add_argument("--recheck", type=positive_int, default=None, metavar="N",
                   help="rerun up to N finished cells (with --only: of that selection) here "
                        "and compare every number with the record; writes nothing")
    s.set_defaults(func=cmd_sweep)
    s = sub.add_parser("aggregate", help="a finished study's cells -> data/results/STUDY.json")
    s.add_argument("study")
    s.add_argument("--budget", default=None)
    s.add_argument("--partial", action="store_true", help="aggregate the cells run so far "
                   "(a grid still accumulating; the file says how many of how many)")
    s.set_defaults(func=cmd_aggregate)
    s = sub.add_parser("seal-cells", help="add digests to cell records written before records "
                       "carried them (once; a damaged record is refused, not sealed)")
    s.set_defaults(func=cmd_seal_cells)
    return p


# -- errors: the library raises, the command explains -------------------------------------------

def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    if isinstance(e, KeyError) and len(text) > 1 and text[0] == text[-1] == "'":
        text = text[1:-1]   # KeyError quotes its message
    return text or type(e).__name__


def _user_errors() -> tuple:
    """The library's errors about the user's input or files: each message names the fault
    and the fix."""
    from dc_lesson import algorithms, tasks
    from dc_lesson.density.softflow import FlowTrainingError
    return (ValueError,            # ConfigError, DemoError, ModelFileError, BudgetError, ...
            TypeError,             # a wrong argument type, named by the check that saw it
            OSError,               # FileNotFoundError (ExpertMissing), permissions, disk full
            tasks.UnknownTaskError, algorithms.UnknownAlgorithmError,
            FlowTrainingError, tasks.PhysicsDiverged)


def main(argv=None) -> int:
    from dc_lesson import budget, tasks
    args = build_parser().parse_args(argv)   # bad sizes end here: argparse's one line, exit 2
    try:
        budget.current()  # fail early on a wrong DC_LESSON_BUDGET
        for name in (getattr(args, "tasks", None) or []) + (getattr(args, "task", None) or []):
            tasks.check_name(name)
        return args.func(args)
    except KeyboardInterrupt:
        print("dc-lesson: interrupted (a resumable run continues from its checkpoint)",
              file=sys.stderr)
        return 130
    except Exception as e:   # noqa: BLE001 - the command's one place to explain errors
        if os.environ.get("DC_LESSON_DEBUG"):
            raise
        if isinstance(e, _user_errors()):
            print(f"dc-lesson: {_one_line(e)}", file=sys.stderr)
            return 2
        print(f"dc-lesson: unexpected {type(e).__name__}: {_one_line(e)} (this is a bug; "
              f"DC_LESSON_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1


__all__ = ["PERFS", "UsageError", "build_parser", "main"]
