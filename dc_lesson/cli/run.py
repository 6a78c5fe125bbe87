"""The commands that run one thing: ``tasks``, ``tour``, ``demos``, ``expert``, ``train`` and
``perf`` (each a thin shell over the library; the library checks, the command explains)."""

from __future__ import annotations

import pathlib
import sys
import time

from dc_lesson.cli._args import UsageError, check_output, command_line, refuse_unused

# The registry's learners (dc_lesson.algorithms.ALGORITHMS; a test keeps the two equal), named
# here so that the command's help does not import torch.
LEARNERS = ("bc", "ppo", "gail", "dc", "dril", "pwil", "ndi", "gpril")

PERFS = {
    "rollout": ("control steps per second of the batched task engine against raw MuJoCo",
                {"tasks", "steps"}),
    "softflow": ("SoftFlow's log-density and training speed against a naive CNF", set()),
    "learners": ("BC, PPO, GAIL and DC per phase, on the path before issue 14 and today's",
                 {"tasks"}),
    "flow-fit": ("DC's density fit under cheaper solvers: time against held-out NLL",
                 {"tasks"}),
    "dc-fit": ("whole DC runs with today's density fit and a cheaper one, paired by seed",
               {"tasks", "seeds", "variant"}),
    "runs": ("whole lesson runs of each learner: an earlier revision's code against today's",
             {"tasks", "before"}),
}


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
    check_output(args.out, folder=True)
    check_output(args.save)
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
        path = write_result(args.save, {"random_returns": stats}, command=command_line(),
                            seeds=[args.seed])
        print(f"wrote {path}")
    return 0


def cmd_demos(args) -> int:
    # the stored experts and demonstrations were made on the fast path (nn.fast): the commands
    # that regenerate them take it too, so a regenerated file is the stored one
    from dc_lesson.nn import fast
    with fast.on():
        return _demos(args)


def _demos(args) -> int:
    from dc_lesson.experts import demos
    if args.first is not None and args.stage != "eval":
        raise UsageError("--first applies to --stage eval only")
    for name in args.task:
        entry = demos.make_demos(name, command=command_line(), stage=args.stage,
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
    from dc_lesson.nn import fast
    with fast.on():   # as cmd_demos: the stored experts were trained on the fast path
        return _expert(args)


def _expert(args) -> int:
    from dc_lesson.data import rollout
    from dc_lesson.experts import DEFAULT_EXPERT, load_expert, network, trained
    if args.what == "eval" and (args.steps is not None or args.restart
                                or args.hours is not None):
        raise UsageError("--steps, --restart and --hours apply to expert train, not expert eval")
    if args.what == "dagger":
        return _dagger(args)
    for name in args.task:
        if args.hours is not None and name not in network.SAC_RECIPES:
            raise UsageError(f"--hours applies to the network experts "
                             f"({', '.join(network.SAC_RECIPES)}), not {name}")
        if args.what == "train":
            if name in network.SAC_RECIPES:
                if args.steps is not None or args.restart:
                    raise UsageError(f"{name}'s expert is SAC + distillation: --steps and "
                                     f"--restart apply to the PPO experts; to train again, "
                                     f"delete {network.paths(name)['checkpoint']}")
                meta = network.train_sac(name, hours=args.hours, command=command_line())
                if not meta["done"]:
                    print(f"{name}: SAC stopped at {meta['steps']:,} of "
                          f"{network.SAC_RECIPES[name].total_steps:,} steps (checkpoint "
                          f"{network.paths(name)['checkpoint']}); resume with: "
                          f"dc-lesson expert train --task {name}")
                    continue
                network.distil_expert(name, command=command_line())
            elif name in trained.PPO_TASKS:
                for unit in trained.EXPERT_UNITS[name]:
                    meta = trained.train_unit(unit, total_steps=args.steps,
                                              command=command_line(), restart=args.restart)
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
        # after training a network expert, that network (on humanoid it is not the default)
        trained_net = args.what == "train" and name in network.SAC_RECIPES
        expert, info = load_expert(name, "network" if trained_net and
                                   DEFAULT_EXPERT[name] != "network" else None)
        r = rollout.returns(rollout.collect(name, expert, args.episodes, seed=1))
        print(f"{name}: expert ({info['name']}) return {r.mean():.1f} ± {r.std():.1f} over "
              f"{len(r)} episodes")
    return 0


def _dagger(args) -> int:
    from dc_lesson.experts import planner_dagger
    if args.steps is not None or args.restart:
        raise UsageError("--steps and --restart apply to expert train; DAgger's rounds are its "
                         "recipe's (experts.planner_dagger.RECIPES)")
    for name in args.task:
        if name not in planner_dagger.RECIPES:
            raise UsageError(f"expert dagger runs on {', '.join(planner_dagger.RECIPES)}, "
                             f"not {name}")
        out = planner_dagger.train(name, hours=args.hours, command=command_line())
        if not out["done"]:
            print(f"{name}: DAgger stopped after round {out['log'][-1]['round']} (labels in "
                  f"{planner_dagger.paths(name)['labels']}); resume with: "
                  f"dc-lesson expert dagger --task {name}")
            continue
        r = out["student_return"]
        print(f"{name}: DAgger student return {r['mean']:.1f} ± {r['std']:.1f} over "
              f"{r['n_episodes']} episodes; saved {planner_dagger.paths(name)['policy']}")
    return 0


def cmd_perf(args) -> int:
    from dc_lesson import budget
    refuse_unused(args.what, PERFS, args, "perf")
    check_output(args.out)
    if args.what == "flow-fit":
        from dc_lesson.perf import flow_fit as perf_flow_fit
        if args.tasks is not None and len(args.tasks) != 1:
            raise UsageError("perf flow-fit runs on one task; give one name to --tasks")
        perf_flow_fit.main(args.tasks, out=args.out, command=command_line())
        return 0
    if args.what == "dc-fit":
        from dc_lesson.perf import dc_fit as perf_dc_fit
        if args.tasks is not None and len(args.tasks) != 1:
            raise UsageError("perf dc-fit runs on one task; give one name to --tasks")
        perf_dc_fit.main(args.tasks, seeds=range(args.seeds or 5), out=args.out,
                         command=command_line(), variant=args.variant or "fit")
        return 0
    if args.what == "learners":
        from dc_lesson.perf import learners as perf_learners
        perf_learners.main(args.tasks or None, args.learners or None, repeats=args.repeats,
                           out=args.out, command=command_line())
        return 0
    if args.what == "runs":
        from dc_lesson.perf import runs as perf_runs
        perf_runs.main(args.before, args.tasks or None, args.learners or None,
                       repeats=args.repeats, out=args.out, command=command_line())
        return 0
    if args.what == "softflow":
        from dc_lesson.perf import softflow as perf_softflow
        return perf_softflow.main(["--save", args.out] if args.out else [])
    from dc_lesson.perf import rollout as perf_rollout
    steps = budget.current().bench_steps if args.steps is None else args.steps
    perf_rollout.main(args.tasks, n_steps=steps, out=args.out, command=command_line())
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
            check_output(path)
    b = budget.current()
    config = learner_config(algo, b, args.seed, args.steps)
    torch.set_num_threads(1)
    demos_of = {}
    for task in args.task:   # every task's demonstrations are checked before any training
        if algo.uses_demos:
            demos_of[task] = data.load_demos(task, n_trajectories=(
                b.il_demos if args.demos is None else args.demos))
    for task in args.task:
        demos = demos_of.get(task)
        start = None
        if algo.uses_demos and algo.name != "bc":   # the protocol: from BC's warm start
            start = algorithms.bc.warm_start_policy(demos, args.seed,
                                                    max_epochs=b.bc_max_epochs)
        t0 = time.time()
        result = algo.train(task, demos, config, policy=start, progress=True)
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


def learner_config(algo, b, seed: int, steps: int | None):
    """The learner's preset at budget ``b``; with ``steps``, for that many environment
    interactions (the budget's ``il_steps``, which every interacting preset reads, replaced).
    A learner whose preset does not read it (BC) refuses ``--steps`` rather than ignore it."""
    import dataclasses

    from dc_lesson.algorithms import ppo
    if steps is None:
        return algo.preset(b, seed)
    config = algo.preset(dataclasses.replace(b, il_steps=steps), seed)
    if isinstance(config, ppo.PPOConfig):   # PPO's smoke preset fixes its own length
        return dataclasses.replace(config, total_steps=steps)
    if config == algo.preset(b, seed) and steps != b.il_steps:
        raise UsageError(f"{algo.name} takes no environment interactions (it learns from the "
                         f"demonstrations alone): leave out --steps")
    return config
