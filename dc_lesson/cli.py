"""The ``dc-lesson`` command.

    dc-lesson tour                 frames of the ten tasks, their specs and random returns,
                                   then BC, GAIL and DC on reacher4 (the book's headline)
    dc-lesson tasks                the spec table
    dc-lesson expert train --task NAME   train (or resume) the expert of NAME with PPO
                                   (a planner's: write its settings)
    dc-lesson demos --task NAME    roll out the expert of NAME into data/demos/
    dc-lesson train LEARNER --task NAME   one learner of the registry (bc, ppo, gail, dc) at
                                   the current budget, evaluated; --save writes its policy
    dc-lesson perf rollout         rollout throughput against raw MuJoCo stepping
    dc-lesson perf softflow        SoftFlow's log_prob and training speed against a naive CNF
    dc-lesson bench softflow-fit --out data/results/softflow_fit.json   what SoftFlow learns
    dc-lesson bench bc --out data/results/bc_demos.json   BC against the number of demos
    dc-lesson bench bc-drift --out data/results/bc_drift.json   BC's drift from the demos
    dc-lesson bench dc --out data/results/dc_modes.json   BC and DC on the multi-mode tasks
    dc-lesson bench dc-ablation --out data/results/dc_ablation.json   loops; averaging vs ADMM
    dc-lesson bench dc-lr --out data/results/dc_lr.json   DC's final return per learning rate
    dc-lesson bench gail --out data/results/gail_modes.json   BC and GAIL on the multi-mode tasks
    dc-lesson bench gail-lr --out data/results/gail_lr.json   GAIL against the learning rate
    dc-lesson sweep STUDY [--only k=v ...] [--dry-run]   a study's cells on Ray (resumable)
    dc-lesson aggregate STUDY      its cells -> data/results/STUDY.json (means, intervals)

Sizes follow ``DC_LESSON_BUDGET`` (smoke | lesson | paper); see ``dc_lesson.budget``.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import shlex
import sys
import time


def _command_line() -> str:
    return "dc-lesson " + " ".join(shlex.quote(a) for a in sys.argv[1:])


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
    b = budget.current()
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
        print(f"\nThe book's headline: BC, GAIL and DC on reacher4 (budget {b.name}; "
              f"--no-headline skips it)")
        headline.run("reacher4", budget=b, out=out)
    if args.save:
        from dc_lesson.storage import write_result
        path = write_result(args.save, {"random_returns": stats}, command=_command_line(),
                            seeds=[args.seed])
        print(f"wrote {path}")
    return 0


def cmd_demos(args) -> int:
    from dc_lesson.experts import demos
    for name in args.task:
        entry = demos.make_demos(name, command=_command_line(), stage=args.stage,
                                 threads=args.threads, first=args.first)
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
                                              command=_command_line())
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


def cmd_perf(args) -> int:
    from dc_lesson import budget
    if args.what == "softflow":
        from dc_lesson.perf import softflow as perf_softflow
        return perf_softflow.main(["--save", args.out] if args.out else [])
    from dc_lesson.perf import rollout as perf_rollout
    steps = args.steps or budget.current().bench_steps
    perf_rollout.main(args.tasks or None, n_steps=steps, out=args.out, command=_command_line())
    return 0


def cmd_train(args) -> int:
    import torch

    from dc_lesson import algorithms, budget, data, evaluation
    from dc_lesson.nn import policies
    algo = algorithms.get(args.learner)
    b = budget.current()
    torch.set_num_threads(1)
    for task in args.task:
        demos = data.load_demos(task, n_trajectories=args.demos or b.il_demos) \
            if algo.uses_demos else None
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
    if args.what == "softflow-fit":
        from dc_lesson.experiments import softflow as bench_softflow
        from dc_lesson import data
        try:
            return bench_softflow.fit_main(args.out, command=_command_line())
        except (data.DemoError, bench_softflow.FitBenchError) as e:
            print(f"dc-lesson: {e}", file=sys.stderr)
            return 2
    if args.what == "bc":
        from dc_lesson.experiments import bc as bench_bc
        from dc_lesson import data
        try:
            bench_bc.main(args.tasks or None, demo_counts=args.demos, seeds=args.seeds,
                          eval_episodes=args.episodes, max_epochs=args.epochs, out=args.out,
                          command=_command_line())
        except (data.DemoError, bench_bc.BenchInputError) as e:
            print(f"dc-lesson: {e}", file=sys.stderr)
            return 2
    elif args.what in ("gail", "gail-lr"):
        from dc_lesson.experiments import bc as bench_bc, gail as bench_gail
        from dc_lesson import data
        try:
            bench_gail.main(args.what, tasks=args.tasks, seeds=args.seeds, steps=args.steps,
                            lr=args.lr, out=args.out, command=_command_line())
        except (data.DemoError, bench_bc.BenchInputError) as e:
            print(f"dc-lesson: {e}", file=sys.stderr)
            return 2
    elif args.what in ("dc", "dc-ablation", "dc-lr"):
        from dc_lesson.experiments import dc as bench_dc
        if args.what == "dc":
            bench_dc.run(args.tasks or bench_dc.TASKS, out=args.out, command=_command_line())
        elif args.what == "dc-ablation":
            bench_dc.run_ablation((args.tasks or ["reacher4"])[0], out=args.out,
                                  command=_command_line())
        else:
            bench_dc.run_lr((args.tasks or [bench_dc.LR_TASK])[0], seeds=args.seeds,
                            steps=args.steps, out=args.out, command=_command_line())
    elif args.what == "bc-drift":
        from dc_lesson.experiments import bc as bench_bc
        from dc_lesson import data
        b = budget.current()
        counts = args.demos or (min(b.bc_demo_counts), max(b.bc_demo_counts))
        try:
            bench_bc.run_drift(args.tasks or bench_bc.available_tasks(), counts,
                               args.seeds or b.bc_seeds[:3],
                               args.episodes or min(20, b.bc_eval_episodes),
                               max_epochs=args.epochs or b.bc_max_epochs, out=args.out,
                               command=_command_line())
        except (data.DemoError, bench_bc.BenchInputError) as e:
            print(f"dc-lesson: {e}", file=sys.stderr)
            return 2
    return 0


def cmd_sweep(args) -> int:
    """``dc-lesson sweep``: dc_lesson.experiments.sweep (its docstring says everything)."""
    from dc_lesson import budget
    from dc_lesson.experiments import aggregate, cells, studies, sweep
    b = budget.get(args.budget) if args.budget else budget.current()
    try:
        study = studies.get(args.study)
        if args.dry_run:
            workers = args.cpus or os.cpu_count() or 1
            print(sweep.format_plan(study, b, sweep.plan(study, b, args.only, workers=workers),
                                    workers))
            return 0
        report = sweep.run(args.study, b, only=args.only, address=args.address, cpus=args.cpus,
                           command=_command_line())
    except (studies.UnknownStudyError, sweep.SweepError, cells.CellError,
            aggregate.AggregateError) as e:
        print(f"dc-lesson: {e}", file=sys.stderr)
        return 2
    print(f"sweep {report.study} ({report.budget}): {report.cells} cells, {report.skipped} "
          f"already done, {report.ran} run, {len(report.failed)} failed, "
          f"{report.wall_seconds:.0f} s" + (f"; wrote {report.aggregate}" if report.aggregate
                                             else ""))
    return 1 if report.failed else 0


def cmd_aggregate(args) -> int:
    from dc_lesson import budget
    from dc_lesson.experiments import aggregate, cells, studies
    b = budget.get(args.budget) if args.budget else budget.current()
    try:
        path = aggregate.write(args.study, b, command=_command_line())
    except (studies.UnknownStudyError, cells.CellError, aggregate.AggregateError) as e:
        print(f"dc-lesson: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dc-lesson", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("tasks", help="list the task ports")
    s.set_defaults(func=cmd_tasks)
    s = sub.add_parser("tour", help="frames, specs and random returns of the ten tasks")
    s.add_argument("--out", default="outputs", help="folder for the figures")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--save", default=None, help="also write the returns to this JSON file")
    s.add_argument("--no-headline", action="store_true",
                   help="skip the closing BC / GAIL / DC comparison on reacher4")
    s.set_defaults(func=cmd_tour)
    s = sub.add_parser("demos", help="roll out a task's expert into data/demos/")
    s.add_argument("--task", nargs="+", required=True)
    s.add_argument("--stage", choices=["demos", "eval"], default=None,
                   help="planner experts: collect only this stage's episodes (run the two "
                        "stages as two processes side by side, then once without --stage)")
    s.add_argument("--first", type=int, default=None,
                   help="with --stage eval: collect that stage's episodes from this one on, "
                        "in a file of their own (a second eval process takes the end)")
    s.add_argument("--threads", type=int, default=None,
                   help="planner experts: mujoco.rollout threads (results do not depend on it)")
    s.set_defaults(func=cmd_demos)
    s = sub.add_parser("expert", help="train or evaluate a task's expert")
    s.add_argument("what", choices=["train", "eval"])
    s.add_argument("--task", nargs="+", required=True)
    s.add_argument("--steps", type=int, default=None, help="override the recipe's total steps")
    s.add_argument("--episodes", type=int, default=10, help="evaluation episodes")
    s.set_defaults(func=cmd_expert)
    s = sub.add_parser("train", help="train one learner of the registry on a task")
    s.add_argument("learner", help="bc, ppo, gail or dc (dc_lesson.algorithms.ALGORITHMS)")
    s.add_argument("--task", nargs="+", required=True)
    s.add_argument("--demos", type=int, default=None,
                   help="demonstrations to learn from (default: the budget's il_demos)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--save", default=None,
                   help="write the policy here ({task} and {learner} are filled in)")
    s.set_defaults(func=cmd_train)
    s = sub.add_parser("perf", help="throughput benchmarks (speed ratios, no science)")
    s.add_argument("what", choices=["rollout", "softflow"])
    s.add_argument("--tasks", nargs="*", default=None)
    s.add_argument("--steps", type=int, default=None, help="rollout: control steps per task")
    s.add_argument("--out", default=None, help="write the figures to this JSON file")
    s.set_defaults(func=cmd_perf)
    s = sub.add_parser("bench", help="the studies behind the book's stored results")
    s.add_argument("what", choices=["bc", "bc-drift", "softflow-fit", "gail",
                                    "gail-lr", "dc", "dc-ablation", "dc-lr"])
    s.add_argument("--tasks", nargs="*", default=None)
    s.add_argument("--steps", type=int, default=None, help="rollout: control steps per task; gail, gail-lr: "
                   "environment interactions per run")
    s.add_argument("--out", default=None, help="write the figures to this JSON file")
    s.add_argument("--demos", type=int, nargs="+", default=None,
                   help="bc: demonstration counts (default: the budget's)")
    s.add_argument("--seeds", type=int, nargs="+", default=None,
                   help="bc: training seeds (default: the budget's)")
    s.add_argument("--episodes", type=int, default=None,
                   help="bc: evaluation episodes per policy (default: the budget's)")
    s.add_argument("--epochs", type=int, default=None,
                   help="bc: maximum training epochs (default: the budget's)")
    s.add_argument("--lr", type=float, default=None,
                   help="gail: one learning rate for the policy, critic and discriminator "
                        "(default: GAILConfig's)")
    s.set_defaults(func=cmd_bench)
    s = sub.add_parser("sweep", help="run a study's cells on Ray (skips finished cells)")
    s.add_argument("study", help="a study of dc_lesson.experiments.studies (bc_demos, ...)")
    s.add_argument("--budget", default=None, help="smoke | lesson | paper (default: "
                   "DC_LESSON_BUDGET)")
    s.add_argument("--only", nargs="+", default=(), metavar="KEY=VALUE",
                   help="keep matching cells: task=reacher4 seed=0,1 learner=bc n_demos=4")
    s.add_argument("--dry-run", action="store_true", help="list the cells and their cost")
    s.add_argument("--address", default=None, help="join this Ray cluster (e.g. auto)")
    s.add_argument("--cpus", type=int, default=None, help="local Ray workers (default: all "
                   "cores)")
    s.set_defaults(func=cmd_sweep)
    s = sub.add_parser("aggregate", help="a finished study's cells -> data/results/STUDY.json")
    s.add_argument("study")
    s.add_argument("--budget", default=None)
    s.set_defaults(func=cmd_aggregate)
    return p


def _algorithms_errors():
    from dc_lesson import algorithms, data
    return (algorithms.UnknownAlgorithmError, algorithms.LearnerInputError, data.DemoError)


def main(argv=None) -> int:
    from dc_lesson import budget, tasks
    args = build_parser().parse_args(argv)
    try:
        budget.current()  # fail early on a wrong DC_LESSON_BUDGET
        for name in (getattr(args, "tasks", None) or []) + (getattr(args, "task", None) or []):
            tasks.check_name(name)
        return args.func(args)
    except (budget.BudgetError, tasks.UnknownTaskError, FileNotFoundError,
            *_algorithms_errors()) as e:
        print(f"dc-lesson: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
