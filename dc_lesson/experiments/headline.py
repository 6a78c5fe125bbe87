"""The book's headline in one command: BC, GAIL and DC on ``reacher4``, side by side.

``dc-lesson tour`` ends with :func:`run`: the paper's Figure 1 and Table I in miniature.  One
seed of the imitation protocol (``budget.il_*``): BC on the first ``il_demos`` demonstrations
(:func:`dc_lesson.algorithms.bc.warm_start`), GAIL and DC from that same start for ``il_steps``
environment interactions each (the settings of Table I's ``gail`` and ``dc`` rows), each policy run
for ``il_eval_episodes`` fresh episodes and measured against all the demonstrations
(:func:`dc_lesson.evaluation.evaluate_policy`).  It saves the mode-coverage figure (where each
policy's fingertip goes) and prints the EMD / KL / reverse-KL table.  About ten minutes at the
``lesson`` budget on a 2-core CPU; the stored, multi-seed version of the same comparison is in
chapter 04.
"""

from __future__ import annotations

import copy
import pathlib
import time

from dc_lesson.algorithms import bc as _bc
from dc_lesson import budget as _budget
from dc_lesson import data as _data
from dc_lesson import algorithms as _algorithms
from dc_lesson import evaluation as _evaluation
from dc_lesson.viz import plots as _plots
from dc_lesson import tasks as _tasks


def run(task: str = "reacher4", seed: int = 0, budget: _budget.Budget | None = None,
        out="outputs", progress: bool = True) -> dict:
    """Trains and measures BC, GAIL and DC on ``task``; returns the measures by method and
    saves ``OUT/headline_coverage.png``."""
    import torch
    from dc_lesson import progress as _progress

    budget = budget or _budget.current()
    spec = _tasks.spec(task)
    reference = _data.load_demos(task)
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    results, features, seconds = {}, {"expert": reference.mode_features}, {}
    stages = _progress.bar(total=3, desc=f"headline: BC, GAIL, DC on {task}", unit="method",
                  enabled=progress)
    try:
        t0 = time.perf_counter()
        start, demos, _ = _bc.warm_start(task, budget.il_demos, seed,
                                         max_epochs=budget.bc_max_epochs)
        seconds["BC"] = time.perf_counter() - t0
        policies = {"BC": start}
        stages.update(1)
        for name in ("GAIL", "DC"):   # both from the same BC start, through the registry
            t0 = time.perf_counter()
            algo = _algorithms.get(name.lower())
            policies[name] = algo.train(task, demos, algo.preset(budget, seed),
                                        policy=copy.deepcopy(start), progress=progress).policy
            seconds[name] = time.perf_counter() - t0
            stages.update(1)
        # The expert row: the expert scored the same way, from the same initial states as the
        # learners (the floor below which a learner's divergence means nothing).
        from dc_lesson.experts import load_expert
        policies = {"expert": load_expert(task)[0], **policies}
        seconds["expert"] = 0.0
        for name, policy in policies.items():
            ev = _evaluation.evaluate_policy(task, policy, reference,
                                             n_episodes=budget.il_eval_episodes,
                                             keep_features=True)
            feats = ev.pop("features")
            if name != "expert":       # the map's "expert" panel is the demonstrations
                features[name] = feats
            results[name] = {**ev, "train_seconds": seconds[name]}
    finally:
        stages.close()
        torch.set_num_threads(old)

    path = pathlib.Path(out) / "headline_coverage.png"
    n_targets = len(spec.modes) if task.startswith("reacher") else None
    title = (f"{task}: where each policy goes (seed {seed}, budget {budget.name}, "
             f"{budget.il_demos} demonstrations, {budget.il_steps:,} interactions)")
    caption = ("'expert': the demonstrations; BC, GAIL and DC: "
               f"{budget.il_eval_episodes} fresh episodes each, mean action. One seed: an "
               "illustration, not a verdict (chapter 04 has the paired intervals).")
    if n_targets:
        fig = _plots.coverage_reacher(features, n_targets)
    else:
        fig = _plots.coverage_velocity(features)
    fig.suptitle(title, fontsize=10, y=1.04)
    fig.text(0.5, -0.04, caption, ha="center", va="top", fontsize=8, wrap=True)
    _plots._save(fig, path)
    import matplotlib.pyplot as plt
    plt.close(fig)
    print(format_table(task, budget, results, seed))
    print(f"saved {path}")
    return results


def format_table(task: str, budget: _budget.Budget, results: dict, seed: int = 0) -> str:
    """The headline's table: one row per policy (the expert's first: the floor), then what
    the columns mean."""
    lines = [f"{task}, seed {seed}, {budget.il_demos} demonstrations, {budget.il_steps:,} "
             f"interactions for GAIL and DC, {budget.il_eval_episodes} evaluation episodes "
             f"(budget {budget.name}):",
             f"{'method':<8}{'EMD':>8}{'KL':>9}{'RKL':>9}{'scaled return':>15}"
             f"{'train s':>9}  modes"]
    for name, r in results.items():
        modes = ", ".join(f"{k} {v:.2f}" for k, v in (r["mode_shares"] or {}).items())
        lines.append(f"{name:<8}{r['emd']:>8.3f}{r['kl']:>9.2f}{r['rkl']:>9.2f}"
                     f"{r['scaled_return']:>15.3f}{r['train_seconds']:>9.0f}  {modes}")
    lines.append("EMD, KL, RKL: to the demonstrations' states, lower is better (the expert row is "
                 "the floor); scaled return: 0 random, 1 expert; modes: shares of episodes by "
                 "the target they arrive at and stay at ('none': nowhere).")
    return "\n".join(lines)


__all__ = ["format_table", "run"]
