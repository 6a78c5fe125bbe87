"""``dc-lesson bench WHAT``: the studies behind the book's first stored results, run in one
process (the book's results now come from cell studies: ``dc-lesson sweep``)."""

from __future__ import annotations

from dc_lesson.cli._args import check_output, command_line, refuse_unused

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


def cmd_bench(args) -> int:
    from dc_lesson import budget
    refuse_unused(args.what, BENCHES, args, "bench", ONE_TASK)
    check_output(args.out)
    b = budget.current()
    if args.what == "softflow-fit":
        from dc_lesson.experiments import softflow as bench_softflow
        return bench_softflow.fit_main(args.out, command=command_line())
    if args.what == "bc":
        from dc_lesson.experiments import bc as bench_bc
        bench_bc.main(args.tasks, demo_counts=args.demos, seeds=args.seeds,
                      eval_episodes=args.episodes, max_epochs=args.epochs, out=args.out,
                      command=command_line())
    elif args.what in ("gail", "gail-lr"):
        from dc_lesson.experiments import gail as bench_gail
        bench_gail.main(args.what, tasks=args.tasks, seeds=args.seeds, steps=args.steps,
                        lr=args.lr, out=args.out, command=command_line())
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
            bench_dc.run(names, out=args.out, command=command_line())
        elif args.what == "dc-ablation":
            bench_dc.run_ablation(names[0], out=args.out, command=command_line())
        else:
            bench_dc.run_lr(names[0], seeds=args.seeds, steps=args.steps, out=args.out,
                            command=command_line())
    elif args.what == "bc-drift":
        from dc_lesson.experiments import bc as bench_bc
        bench_bc.run_drift(args.tasks or bench_bc.available_tasks(),
                           (min(b.bc_demo_counts), max(b.bc_demo_counts)) if args.demos is None
                           else args.demos,
                           b.bc_seeds[:3] if args.seeds is None else args.seeds,
                           min(20, b.bc_eval_episodes) if args.episodes is None
                           else args.episodes,
                           max_epochs=b.bc_max_epochs if args.epochs is None else args.epochs,
                           out=args.out, command=command_line())
    return 0
