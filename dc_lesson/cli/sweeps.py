"""``dc-lesson sweep`` and ``dc-lesson aggregate``: a study's cells on Ray, and their aggregate
(:mod:`dc_lesson.experiments.sweep` says everything a sweep does)."""

from __future__ import annotations

import os
import sys
import time

from dc_lesson.cli._args import command_line

def cmd_sweep(args) -> int:
    """``dc-lesson sweep``: dc_lesson.experiments.sweep (its docstring says everything)."""
    from dc_lesson import budget
    from dc_lesson.experiments import aggregate, cells, studies, sweep
    b = budget.get(args.budget) if args.budget else budget.current()
    if args.recheck is not None and (args.study == "all" or args.dry_run or args.hours
                                     or args.priced_since or args.priced_until
                                     or args.address or args.cpus):
        print("dc-lesson: --recheck reruns finished cells of one study here; it takes "
              "--only and --budget, not 'all', --dry-run, --priced-*, --hours, --address "
              "or --cpus", file=sys.stderr)
        return 2
    if args.study == "all":
        return _sweep_all(args, b)
    try:
        study = studies.get(args.study)
        if args.recheck is not None:
            from dc_lesson.experiments import recheck
            rows = recheck.recheck(args.study, b, args.only, args.recheck)
            same = sum(r["identical"] for r in rows)
            print(f"recheck {args.study} ({b.name}): {same} of {len(rows)} cells identical to "
                  "their records (README, Sweeps: what a difference on another platform means)")
            # a difference on the record's own platform is the code's: a failure
            return 1 if any(r["same_platform"] and not r["identical"] for r in rows) else 0
        if args.dry_run:
            workers = args.cpus or os.cpu_count() or 1
            print(sweep.format_plan(study, b, sweep.plan(study, b, args.only, workers=workers),
                                    workers))
            if args.priced_since:
                print(sweep.format_reprice(sweep.reprice(study, b, args.priced_since,
                                                         args.only, workers=workers,
                                                         until=args.priced_until)))
            elif args.priced_until:
                raise sweep.SweepError("--priced-until ends a --priced-since window; add "
                                       "--priced-since")
            return 0
        if args.priced_since or args.priced_until:
            raise sweep.SweepError("--priced-since prices a --dry-run; add --dry-run")
        report = sweep.run(args.study, b, only=args.only, address=args.address, cpus=args.cpus,
                           command=command_line(), hours=args.hours)
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
                               command=command_line(), hours=hours)
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
        path = aggregate.write(args.study, b, command=command_line(), partial=args.partial)
    except (studies.UnknownStudyError, cells.CellError, aggregate.AggregateError) as e:
        print(f"dc-lesson: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


def cmd_seal_cells(args) -> int:
    """``dc-lesson seal-cells``: :func:`dc_lesson.experiments.cells.seal` on the data folder."""
    from dc_lesson.experiments import cells
    sealed, already = cells.seal()
    print(f"{cells.cells_root()}: sealed {sealed} records, {already} already carried digests")
    return 0
