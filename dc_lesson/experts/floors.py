"""The competence floors the experts are held to, and a check of each shipped expert.

The floors (dm_control's reward scale, 0 to 1000 per episode) are the project's bar for "a
clearly competent expert" (issue 3).  Where an expert falls short we ship it anyway, because
imitation still needs demonstrations, and say so: :func:`report` gives, per task, the floor,
what was measured and whether it holds, read from the demonstrations' manifest and files.

How each floor is judged:

* the expert's mean return over its 50 evaluation episodes (``expert_return`` in the
  manifest; for a planner expert, its 25 demonstrations and 25 further episodes, see
  :mod:`dc_lesson.experts.demos`) must reach the floor;
* multi-mode tasks (``reacher2``, ``reacher4``, ``halfcheetah2``): also every mode, judged on
  the demonstrations that took it (mean return of those episodes), since "each target
  reached and held" and "300 in each direction" are per-mode promises.  The manifest's
  ``none`` class (an episode that arrived at no mode) is not a mode an expert must take: it
  is counted instead, and more than ``MAX_NONE_SHARE`` of the demonstrations arriving
  nowhere misses the floor (a competent expert arrives);
* ``hopper``: the floor is "hops forward for the whole episode without falling", which a
  mean return alone cannot say (standing still pays a quarter, 250 per episode; 400 is what
  hopping at 0.6 m/s without a fall pays).  So also, in every demonstration, the mean forward
  speed must be at least ``HOP_SPEED`` m/s and the torso must stay above ``STAND_HEIGHT``
  (0.7 m, Gym's healthy height, which the task's reward also tests) in at least 95% of the
  steps.

A floor on return says nothing about whether a learner can imitate the expert: a sampling
planner meets every floor and is no Markov policy.  So :func:`report` also gives BC's scaled
return from 25 of the expert's demonstrations, as the ``clonable`` study measured it
(``data/results/clonable.json``: the mean over its seeds, 50 episodes each), and calls the
expert *clonable* when it reaches ``CLONE_FLOOR`` (issue 39's bar).
"""

from __future__ import annotations

import numpy as np

from dc_lesson.tasks.base import NO_MODE

FLOORS: dict[str, float] = {
    "cartpole": 750, "reacher1": 700, "reacher2": 700, "reacher4": 700, "halfcheetah": 350,
    "halfcheetah2": 300, "walker": 700, "hopper": 400, "ant": 400, "humanoid": 300,
}
HOP_SPEED = 0.2          # m/s: slower than this is standing, not hopping forward
STAND_HEIGHT = 0.7       # m: Gym's healthy torso height, part of the hopper task's reward
NONE_CLASS = "none"      # the mode shares' name for episodes that arrived at no mode
MAX_NONE_SHARE = 0.1     # at most this share of the demonstrations may arrive nowhere
CLONE_FLOOR = 0.5        # BC's scaled return from 25 demonstrations for "clonable"


def check(task: str, entry: dict, trajectories) -> dict:
    """The floor of ``task`` against its manifest ``entry`` and demonstration records."""
    floor = FLOORS[task]
    mean = entry["expert_return"]["mean"]
    row = {"task": task, "floor": floor, "expert return": mean,
           "expert std": entry["expert_return"]["std"], "method": entry["expert"]["name"]}
    ok = mean >= floor
    detail = []
    shares = entry["demo_mode_shares"]
    names = [n for n in shares if n != NONE_CLASS]
    if len(names) > 1:
        returns = np.array([t.ret for t in trajectories])
        modes = np.array([t.mode for t in trajectories])
        nowhere = float(np.mean(modes == NO_MODE)) if len(modes) else 0.0
        if nowhere > MAX_NONE_SHARE:
            ok = False
        if nowhere > 0:
            detail.append(f"{nowhere:.0%} of demonstrations arrived nowhere")
        for k, name in enumerate(names):
            r = returns[modes == k]
            if len(r) == 0:
                ok = False
                detail.append(f"{name}: no demonstration")
            else:
                ok &= bool(r.mean() >= floor)
                detail.append(f"{name} {r.mean():.0f}")
    if task == "hopper":
        speeds = np.array([t.mode_features[1:, 1].mean() for t in trajectories])
        standing = np.array([(t.mode_features[1:, 0] >= STAND_HEIGHT).mean()
                             for t in trajectories])
        hops = bool((speeds >= HOP_SPEED).all() and (standing >= 0.95).all())
        ok &= hops
        detail.append(f"mean speed {speeds.mean():.2f} m/s (min {speeds.min():.2f}), "
                      f"standing {standing.min():.0%} of steps at worst")
    row["per mode / behaviour"] = "; ".join(detail)
    row["meets floor"] = bool(ok)
    return row


def bc_from_25(results_dir=None) -> dict[str, float]:
    """BC's mean scaled return from 25 demonstrations of each task's default expert, from the
    stored ``clonable`` aggregate (empty when it is not there)."""
    from dc_lesson import storage
    path = (storage.DATA / "results" if results_dir is None else results_dir) / "clonable.json"
    if not path.is_file():
        return {}
    fix = "rebuild it with: dc-lesson aggregate clonable"
    table, = storage.json_fields(storage.read_json(path, "result file", fix), path,
                                 "result file", fix, "table")
    try:
        return {r["task"]: float(r["scaled_return_mean"]) for r in table
                if r.get("demonstrations") == r.get("task")}
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise storage.UnreadableFileError(f"result file {path} has a table row without a task "
                                          f"or a scaled return ({type(e).__name__}: {e}); "
                                          f"{fix}") from None


def report(directory=None, results_dir=None) -> list[dict]:
    """:func:`check` for every task with shipped demonstrations, in the tasks' order, with BC's
    stored score from 25 demonstrations beside it (``clonable``: at least ``CLONE_FLOOR``;
    None where the study has no such row: the multi-mode tasks, which Table I covers)."""
    from dc_lesson import data
    from dc_lesson import tasks as _tasks
    manifest = data.read_manifest(directory)["tasks"]
    bc_scores = bc_from_25(results_dir)
    rows = []
    for task in _tasks.NAMES:
        if task in manifest:
            demos = data.load_demos(task, directory=directory)
            rows.append(check(task, manifest[task], demos.trajectories))
            bc = bc_scores.get(task)
            rows[-1]["BC from 25 demos"] = bc
            rows[-1]["clonable"] = None if bc is None else bool(bc >= CLONE_FLOOR)
        else:
            rows.append({"task": task, "floor": FLOORS[task], "meets floor": False,
                         "method": "no demonstrations yet"})
    return rows
