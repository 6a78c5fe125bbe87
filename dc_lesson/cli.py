"""The dc-lesson command: every study of the book, from the command line.

  dc-lesson tour                        the ten tasks (frames, sizes, random returns),
                                        then BC, GAIL and DC on reacher4: the headline
  dc-lesson tasks                       the table of task sizes and horizons
  dc-lesson expert train --task NAME    train (or resume) the PPO expert of NAME
                                        (a planner expert: write its settings)
  dc-lesson expert eval --task NAME     measure the expert of NAME (--episodes N)
  dc-lesson demos --task NAME           roll out the expert of NAME into data/demos/
  dc-lesson train LEARNER --task NAME   train one learner (bc, ppo, gail, dc) at the
                                        budget and evaluate it; --save writes its policy
  dc-lesson perf WHAT                   speed benchmarks (dc-lesson perf -h lists them)
  dc-lesson bench WHAT --out FILE       the studies behind the book's stored results
                                        (dc-lesson bench -h describes each)
  dc-lesson sweep STUDY [--dry-run]     a study's cells on Ray (resumable, accumulating);
                                        STUDY all: every study (--dry-run: the ledger)
  dc-lesson aggregate STUDY             its cells -> data/results/STUDY.json (intervals)

Sizes follow the budget: set DC_LESSON_BUDGET to smoke (seconds, numbers mean nothing),
lesson (the default, minutes) or paper (the paper's sizes, hours). A wrong value, a missing
or damaged file, or an output that cannot be written stops the command before any compute
with one line saying what is wrong and how to fix it, and exit status 2.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import shlex
import sys
import time

# What each benchmark studies and which options it reads; an option it does not read is
# refused rather than silently ignored.
BENCHES = {
    "bc": ("BC's return against the number of demonstrations (the paper's Table I, BC rows)",
           {"tasks", "demos", "seeds", "episodes", "epochs"}),
    "bc-drift": ("how far BC's states drift from the demonstrations over an episode",
                 {"tasks", "demos", "seeds", "episodes", "epochs"}),
    "softflow-fit": ("what SoftFlow learns: its fit of each task's demonstration states",
                     set()),
    "gail": ("BC and GAIL on the multi-mode tasks: returns and mode coverage",
             {"tasks", "seeds", "steps", "lr"}),
    "gail-lr": ("GAIL's final return for each learning rate (the paper's Figure 4)",
                {"tasks", "seeds", "steps"}),
    "dc": ("BC and DC on the multi-mode tasks: returns and mode coverage (Table I)",
           {"tasks"}),
    "dc-ablation": ("DC with 1 to 4 loops, and averaging against consensus ADMM (Figure 3)",
                    {"tasks"}),
    "dc-lr": ("DC's final return for each learning rate (Figure 4)",
              {"tasks", "seeds", "steps"}),
}
ONE_TASK = {"gail-lr", "dc-ablation", "dc-lr"}
PERFS = {
    "rollout": ("control steps per second of the batched task engine against raw MuJoCo",
                {"tasks", "steps"}),
    "softflow": ("SoftFlow's log-density and training speed against a naive CNF", set()),
    "learners": ("BC, PPO, GAIL and DC per phase, on the path before issue 14 and today's",
                 {"tasks"}),
}
BENCH_OPTIONS = {"tasks": "--tasks", "demos": "--demos", "seeds": "--seeds",
                 "episodes": "--episodes", "epochs": "--epochs", "steps": "--steps",
                 "lr": "--lr"}


class UsageError(ValueError):
    """A combination of options the command does not take."""


class Parser(argparse.ArgumentParser):
    """argparse with a one-line refusal: the error and where the help is (no usage dump)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see: {self.prog} -h)\n")


def _command_line() -> str:
    return "dc-lesson " + " ".join(shlex.quote(a) for a in sys.argv[1:])


# -- argument types: a size of 0 or below is an error, never a request for the default ---------

def _whole_number(minimum: int, what: str):
    """An argparse type: a whole number of at least ``minimum``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{what} {minimum}{' or more' if minimum == 0 else ''}"
                                             f", got {value}")
        return value
    return parse


positive_int = _whole_number(1, "must be at least")
seed_int = _whole_number(0, "a seed must be")


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def _check_output(path, folder: bool = False):
    """An output path is checked before any compute (it would be lost at the end otherwise)."""
    from dc_lesson.storage import check_writable
    return None if path is None else check_writable(path, folder=folder)


# -- the commands -------------------------------------------------------------------------------

def cmd_tasks(args) -> int:
    from dc_lesson import tasks
    for row in tasks.spec_table():
        print(f"{row['task']:<13} obs {row['obs']:>3}  act {row['act']:>2}  horizon "
              f"{row['horizon']}  dt {row['control dt (s)']:.3f}s  mode: {row['mode feature']}"
              f"  [{row['dm_control base']}]")
    return 0


def cmd_tour(args) -> int:
    from dc_lesson import budget, tasks
    from dc_lesson.viz import plots
    from dc_lesson.experiments import tour
    _check_output(args.out, folder=True)
    _check_output(args.save)
    b = budget.current()
    if not args.no_headline:
        from dc_lesson import data
        data.load_demos("reacher4")   # a damaged demonstration file stops the tour now
    out = pathlib.Path(args.out)
    t0 = time.time()
    names = list(tasks.NAMES)
    print(f"budget: {b.name} ({b.tour_episodes} random episodes per task)")
    fig = plots.gallery(tour.frames(names), names, path=out / "tour_tasks.png")
    stats = tour.random_returns(names, b.tour_episodes, seed=args.seed)
    plots.return_bars(names, [stats[n]["mean"] for n in names], [stats[n]["std"] for n in names],
                      title="random policy", path=out / "tour_random_returns.png")
    del fig
    print(f"\n{'task':<13}{'paper task':<40}{'obs':>4}{'act':>4}{'random return':>18}")
    for n in names:
        s = tasks.SPECS[n]
        print(f"{n:<13}{s.paper_task:<40}{s.obs_dim:>4}{s.act_dim:>4}"
              f"{stats[n]['mean']:>11.1f} ± {stats[n]['std']:<5.1f}")
    print(f"\nsaved {out / 'tour_tasks.png'} and {out / 'tour_random_returns.png'} "
          f"in {time.time() - t0:.0f} s")
    if not args.no_headline:
        from dc_lesson.experiments import headline
        print(f"\nThe book's headline: BC, GAIL and DC on reacher4 (budget {b.name}, seed "
              f"{args.seed}; --no-headline skips it)")
        headline.run("reacher4", seed=args.seed, budget=b, out=out)
    if args.save:
        from dc_lesson.storage import write_result
        path = write_result(args.save, {"random_returns": stats}, command=_command_line(),
                            seeds=[args.seed])
        print(f"wrote {path}")
    return 0


def cmd_demos(args) -> int:
    from dc_lesson.experts import demos
    if args.first is not None and args.stage != "eval":
        raise UsageError("--first applies to --stage eval only")
    for name in args.task:
        entry = demos.make_demos(name, command=_command_line(), stage=args.stage,
                                 threads=args.threads, first=args.first,
                                 variant=args.variant)
        if entry is None:
            print(f"{name}: stage {args.stage!r} complete in data/demos/partial/; finish with: "
                  f"dc-lesson demos --task {name}")
            continue
        e, r = entry["expert_return"], entry["random_return"]
        shares = ", ".join(f"{k} {v:.2f}" for k, v in entry["demo_mode_shares"].items())
        print(f"{name}: {entry['n_trajectories']} demonstrations; expert {e['mean']:.1f} ± "
              f"{e['std']:.1f}, random {r['mean']:.1f} ± {r['std']:.1f} over "
              f"{e['n_episodes']} episodes; modes: {shares}; {entry['wall_seconds']:.0f} s")
    return 0


def cmd_expert(args) -> int:
    from dc_lesson.data import rollout
    from dc_lesson.experts import load_expert, planner, trained
    if args.what == "eval" and (args.steps is not None or args.restart):
        raise UsageError("--steps and --restart apply to expert train, not expert eval")
    for name in args.task:
        if args.what == "train":
            if name in planner.PLANNERS:
                planner.write_settings(name, command=_command_line())
                print(f"{name}: the expert is a planner, nothing to train; its settings are in "
                      f"{planner.settings_path(name)}; evaluating it costs minutes per episode: "
                      f"dc-lesson expert eval --task {name} --episodes N")
                continue
            elif name in trained.EXPERT_UNITS:
                for unit in trained.EXPERT_UNITS[name]:
                    meta = trained.train_unit(unit, total_steps=args.steps,
                                              command=_command_line(), restart=args.restart)
                    if meta.get("restarted"):
                        print(f"{unit}: --restart discarded the checkpoint "
                              f"{trained.unit_paths(unit)['checkpoint']} and trained from the "
                              f"first update")
                    print(f"{unit}: {meta['steps']} steps, {meta['training_seconds']:.0f} s of "
                          f"training; saved {trained.unit_paths(unit)['policy']}")
            else:
                print(f"dc-lesson: {name} has a scripted expert; nothing to train",
                      file=sys.stderr)
                continue
        expert, info = load_expert(name)
        r = rollout.returns(rollout.collect(name, expert, args.episodes, seed=1))
        print(f"{name}: expert ({info['name']}) return {r.mean():.1f} ± {r.std():.1f} over "
              f"{len(r)} episodes")
    return 0


def _refuse_unused(what: str, table: dict, args, command: str) -> None:
    used = table[what][1]
    given = [BENCH_OPTIONS[k] for k in BENCH_OPTIONS
             if getattr(args, k, None) is not None and k not in used]
    if given:
        raise UsageError(f"{command} {what} does not take {', '.join(given)}; it reads "
                         f"{', '.join(BENCH_OPTIONS[k] for k in BENCH_OPTIONS if k in used) or 'only --out'}")
    if what in ONE_TASK and args.tasks is not None and len(args.tasks) != 1:
        raise UsageError(f"{command} {what} runs on one task; give one name to --tasks")
    if args.tasks is not None and not args.tasks:
        raise UsageError(f"--tasks needs at least one task name (leave it out for the "
                         f"default tasks)")


def cmd_perf(args) -> int:
    from dc_lesson import budget
    _refuse_unused(args.what, PERFS, args, "perf")
    _check_output(args.out)
    if args.what == "learners":
        from dc_lesson.perf import learners as perf_learners
        perf_learners.main(args.tasks or None, args.learners or None, repeats=args.repeats,
                           out=args.out, command=_command_line())
        return 0
    if args.what == "softflow":
        from dc_lesson.perf import softflow as perf_softflow
        return perf_softflow.main(["--save", args.out] if args.out else [])
    from dc_lesson.perf import rollout as perf_rollout
    steps = budget.current().bench_steps if args.steps is None else args.steps
    perf_rollout.main(args.tasks, n_steps=steps, out=args.out, command=_command_line())
    return 0


def cmd_train(args) -> int:
    import torch

    from dc_lesson import algorithms, budget, data, evaluation
    from dc_lesson.nn import policies
    algo = algorithms.get(args.learner)
    if args.demos is not None and not algo.uses_demos:
        raise UsageError(f"{algo.name} learns from the task's reward, not from "
                         f"demonstrations: leave out --demos")
    if args.save:
        for task in args.task:
            try:
                path = args.save.format(task=task, learner=algo.name)
            except (KeyError, IndexError, ValueError):
                raise UsageError(f"--save {args.save!r}: only {{task}} and {{learner}} can be "
                                 f"filled in") from None
            _check_output(path)
    b = budget.current()
    torch.set_num_threads(1)
    demos_of = {}
    for task in args.task:   # every task's demonstrations are checked before any training
        if algo.uses_demos:
            demos_of[task] = data.load_demos(task, n_trajectories=(
                b.il_demos if args.demos is None else args.demos))
    for task in args.task:
        demos = demos_of.get(task)
        start = None
        if args.learner in ("gail", "dc"):   # the paper's protocol: from BC's warm start
            start = algorithms.bc.warm_start_policy(demos, args.seed,
                                                    max_epochs=b.bc_max_epochs)
        t0 = time.time()
        result = algo.train(task, demos, algo.preset(b, args.seed), policy=start,
                            progress=True)
        ev = evaluation.evaluate_policy(task, result.policy, n_episodes=b.il_eval_episodes)
        print(f"{task}: {algo.name} (budget {b.name}, seed {args.seed}) trained in "
              f"{time.time() - t0:.0f} s; scaled return {ev['scaled_return']:.3f}, "
              f"return {ev['return']:.1f} over {b.il_eval_episodes} episodes")
        if args.save:
            path = pathlib.Path(args.save.format(task=task, learner=algo.name))
            policies.save_policy(result.policy, path, meta={"task": task, "algorithm": algo.name,
                                                            "seed": args.seed, "budget": b.name})
            print(f"saved {path}")
    return 0


def cmd_bench(args) -> int:
    from dc_lesson import budget
    _refuse_unused(args.what, BENCHES, args, "bench")
    _check_output(args.out)
    b = budget.current()
    if args.what == "softflow-fit":
        from dc_lesson.experiments import softflow as bench_softflow
        return bench_softflow.fit_main(args.out, command=_command_line())
    if args.what == "bc":
        from dc_lesson.experiments import bc as bench_bc
        bench_bc.main(args.tasks, demo_counts=args.demos, seeds=args.seeds,
                      eval_episodes=args.episodes, max_epochs=args.epochs, out=args.out,
                      command=_command_line())
    elif args.what in ("gail", "gail-lr"):
        from dc_lesson.experiments import gail as bench_gail
        bench_gail.main(args.what, tasks=args.tasks, seeds=args.seeds, steps=args.steps,
                        lr=args.lr, out=args.out, command=_command_line())
    elif args.what in ("dc", "dc-ablation", "dc-lr"):
        from dc_lesson import data
        from dc_lesson.experiments import dc as bench_dc
        if args.what == "dc":
            names = args.tasks or list(bench_dc.TASKS)
        else:
            names = args.tasks or [bench_dc.LR_TASK if args.what == "dc-lr" else "reacher4"]
        for name in names:   # a damaged demonstration file stops the study before it starts
            data.load_demos(name)
        if args.what == "dc":
            bench_dc.run(names, out=args.out, command=_command_line())
        elif args.what == "dc-ablation":
            bench_dc.run_ablation(names[0], out=args.out, command=_command_line())
        else:
            bench_dc.run_lr(names[0], seeds=args.seeds, steps=args.steps, out=args.out,
                            command=_command_line())
    elif args.what == "bc-drift":
        from dc_lesson.experiments import bc as bench_bc
        bench_bc.run_drift(args.tasks or bench_bc.available_tasks(),
                           (min(b.bc_demo_counts), max(b.bc_demo_counts)) if args.demos is None
                           else args.demos,
                           b.bc_seeds[:3] if args.seeds is None else args.seeds,
                           min(20, b.bc_eval_episodes) if args.episodes is None
                           else args.episodes,
                           max_epochs=b.bc_max_epochs if args.epochs is None else args.epochs,
                           out=args.out, command=_command_line())
    return 0


def cmd_sweep(args) -> int:
    """``dc-lesson sweep``: dc_lesson.experiments.sweep (its docstring says everything)."""
    from dc_lesson import budget
    from dc_lesson.experiments import aggregate, cells, studies, sweep
    b = budget.get(args.budget) if args.budget else budget.current()
    if args.study == "all":
        return _sweep_all(args, b)
    try:
        study = studies.get(args.study)
        if args.dry_run:
            workers = args.cpus or os.cpu_count() or 1
            print(sweep.format_plan(study, b, sweep.plan(study, b, args.only, workers=workers),
                                    workers))
            return 0
        report = sweep.run(args.study, b, only=args.only, address=args.address, cpus=args.cpus,
                           command=_command_line(), hours=args.hours)
    except (studies.UnknownStudyError, sweep.SweepError, cells.CellError,
            aggregate.AggregateError) as e:
        print(f"dc-lesson: {e}", file=sys.stderr)
        return 2
    print(f"sweep {report.study} ({report.budget}): {report.cells} cells, {report.skipped} "
          f"already done, {report.ran} run, {len(report.failed)} failed, "
          f"{report.wall_seconds:.0f} s" + (f"; wrote {report.aggregate}" if report.aggregate
                                             else "")
          + (f"; {report.deferred} left at the deadline (--hours)" if report.deferred else ""))
    return 1 if report.failed else 0


def _sweep_all(args, b) -> int:
    """``dc-lesson sweep all``: every study in turn (``--dry-run``: the ledger of the whole
    grid, done and left, with its CPU time)."""
    from dc_lesson.experiments import aggregate, cells, studies, sweep
    workers = args.cpus or os.cpu_count() or 1
    if args.only:
        print("dc-lesson: --only selects cells of one study; name the study instead of 'all'",
              file=sys.stderr)
        return 2
    if args.dry_run:
        print(sweep.format_ledger(sweep.ledger(b, workers=workers), b, workers))
        return 0
    failed = 0
    deadline = None if args.hours is None else time.time() + 3600.0 * args.hours
    for name in studies.BOOK:
        hours = None if deadline is None else (deadline - time.time()) / 3600.0
        if hours is not None and hours <= 0:
            print(f"dc-lesson: the deadline (--hours) has passed; {name} and the studies after "
                  "it are left for the next run")
            break
        try:
            report = sweep.run(name, b, address=args.address, cpus=args.cpus,
                               command=_command_line(), hours=hours)
        except (sweep.SweepError, cells.CellError, aggregate.AggregateError) as e:
            print(f"dc-lesson: {name}: {e}", file=sys.stderr)
            return 2
        failed += len(report.failed)
        print(f"sweep {name} ({report.budget}): {report.ran} run, {report.skipped} already "
              f"done, {len(report.failed)} failed")
    return 1 if failed else 0


def cmd_aggregate(args) -> int:
    from dc_lesson import budget
    from dc_lesson.experiments import aggregate, cells, studies
    b = budget.get(args.budget) if args.budget else budget.current()
    try:
        path = aggregate.write(args.study, b, command=_command_line(), partial=args.partial)
    except (studies.UnknownStudyError, cells.CellError, aggregate.AggregateError) as e:
        print(f"dc-lesson: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


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
                   help="planner experts only (ant, walker, humanoid): collect only this "
                        "stage's episodes; run the two stages as two processes side by side, "
                        "then once without --stage to combine them")
    s.add_argument("--first", type=positive_int, default=None,
                   help="with --stage eval: collect that stage's episodes from this one on, "
                        "in a file of their own (a second eval process takes the end)")
    s.add_argument("--threads", type=positive_int, default=None,
                   help="planner experts: mujoco.rollout threads (results do not depend on it)")
    s.add_argument("--variant", default=None,
                   help="another expert of the task: 'coin' (reacher2, reacher4, halfcheetah2: "
                        "the mode drawn by a hidden coin per episode)")
    s.set_defaults(func=cmd_demos)
    s = sub.add_parser("expert", help="train or evaluate a task's expert",
                       description="expert train: train (or resume from its checkpoint) the PPO "
                                   "expert of a task, then evaluate it.\nexpert eval: "
                                   "evaluate the expert of a task.", formatter_class=raw)
    s.add_argument("what", choices=["train", "eval"], help="train or eval")
    s.add_argument("--task", nargs="+", required=True, help="one or more task names")
    s.add_argument("--steps", type=positive_int, default=None,
                   help="train: total environment steps instead of the recipe's")
    s.add_argument("--restart", action="store_true",
                   help="train: discard the checkpoint (even a committed one made with another "
                        "configuration) and train from the first update")
    s.add_argument("--episodes", type=positive_int, default=10,
                   help="evaluation episodes (default: 10)")
    s.set_defaults(func=cmd_expert)
    s = sub.add_parser("train", help="train one learner (bc, ppo, gail, dc) on a task")
    s.add_argument("learner", help="bc, ppo, gail or dc")
    s.add_argument("--task", nargs="+", required=True, help="one or more task names")
    s.add_argument("--demos", type=positive_int, default=None,
                   help="demonstrations to learn from (default: the budget's il_demos)")
    s.add_argument("--seed", type=seed_int, default=0, help="the run's seed (default: 0)")
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
    s.set_defaults(func=cmd_perf)
    s = sub.add_parser("bench", help="the studies behind the book's stored results",
                       description="The studies behind the book's stored results (sizes from "
                                   "the budget unless given):\n" + _choices_help(BENCHES),
                       formatter_class=raw)
    s.add_argument("what", choices=list(BENCHES), metavar="WHAT", help=", ".join(BENCHES))
    s.add_argument("--tasks", nargs="*", default=None,
                   help="task names (default: each study's own; gail-lr, dc-ablation and "
                        "dc-lr take one)")
    s.add_argument("--steps", type=positive_int, default=None,
                   help="gail, gail-lr, dc-lr: environment interactions per run")
    s.add_argument("--out", default=None, help="write the result to this JSON file")
    s.add_argument("--demos", type=positive_int, nargs="+", default=None,
                   help="bc, bc-drift: demonstration counts (default: the budget's)")
    s.add_argument("--seeds", type=seed_int, nargs="+", default=None,
                   help="bc, bc-drift, gail, gail-lr, dc-lr: training seeds (default: the "
                        "budget's)")
    s.add_argument("--episodes", type=positive_int, default=None,
                   help="bc, bc-drift: evaluation episodes per policy (default: the budget's)")
    s.add_argument("--epochs", type=positive_int, default=None,
                   help="bc, bc-drift: maximum training epochs (default: the budget's)")
    s.add_argument("--lr", type=positive_float, default=None,
                   help="gail: one learning rate for the policy, critic and discriminator "
                        "(default: GAILConfig's)")
    s.set_defaults(func=cmd_bench)
    s = sub.add_parser("sweep", help="run a study's cells on Ray (skips finished cells)")
    s.add_argument("study", help="a study of dc_lesson.experiments.studies (bc_demos, ...), "
                   "or all (every study in turn; with --dry-run the whole grid's ledger)")
    s.add_argument("--budget", default=None, help="smoke | lesson | paper (default: "
                   "DC_LESSON_BUDGET)")
    s.add_argument("--only", nargs="+", default=(), metavar="KEY=VALUE",
                   help="keep matching cells: task=reacher4 seed=0,1 learner=bc n_demos=4")
    s.add_argument("--dry-run", action="store_true", help="list the cells and their cost")
    s.add_argument("--address", default=None, help="join this Ray cluster (e.g. auto)")
    s.add_argument("--cpus", type=int, default=None, help="local Ray workers (default: all "
                   "cores)")
    s.add_argument("--hours", type=positive_float, default=None,
                   help="start only the cells whose estimated cost ends within this many "
                        "hours; running cells finish (a session's length)")
    s.set_defaults(func=cmd_sweep)
    s = sub.add_parser("aggregate", help="a finished study's cells -> data/results/STUDY.json")
    s.add_argument("study")
    s.add_argument("--budget", default=None)
    s.add_argument("--partial", action="store_true", help="aggregate the cells run so far "
                   "(a grid still accumulating; the file says how many of how many)")
    s.set_defaults(func=cmd_aggregate)
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


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
