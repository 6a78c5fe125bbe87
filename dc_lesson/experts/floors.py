"""The competence floors the experts are held to, and a check of each shipped expert.

The floors (dm_control's reward scale, 0 to 1000 per episode) are the project's bar for "a
clearly competent expert" (issue 3).  Where an expert falls short we ship it anyway, because
imitation still needs demonstrations, and say so: :func:`report` gives, per task, the floor,
what was measured and whether it holds, read from the demonstrations' manifest and files.

How each floor is judged:

* the expert's mean return over its 50 evaluation episodes (``expert_return`` in the
  manifest; for a planner expert, its 25 demonstrations and 25 further episodes, see
  :mod:`dc_lesson.demos`) must reach the floor;
* multi-mode tasks (``reacher2``, ``reacher4``, ``halfcheetah2``): also every mode, judged on
  the demonstrations that took it (mean return of those episodes), since "each target
  reached and held" and "300 in each direction" are per-mode promises;
* ``hopper``: the floor is "hops forward for the whole episode without falling", which a
  mean return alone cannot say (standing still pays a quarter, 250 per episode; 400 is what
  hopping at 0.6 m/s without a fall pays).  So also, in every demonstration, the mean forward
  speed must be at least ``HOP_SPEED`` m/s and the torso must stay above ``STAND_HEIGHT``
  (0.7 m, Gym's healthy height, which the task's reward also tests) in at least 95% of the
  steps.
"""

from __future__ import annotations

import numpy as np

FLOORS: dict[str, float] = {
    "cartpole": 750, "reacher1": 700, "reacher2": 700, "reacher4": 700, "halfcheetah": 350,
    "halfcheetah2": 300, "walker": 700, "hopper": 400, "ant": 400, "humanoid": 300,
}
HOP_SPEED = 0.2          # m/s: slower than this is standing, not hopping forward
STAND_HEIGHT = 0.7       # m: Gym's healthy torso height, part of the hopper task's reward


def check(task: str, entry: dict, trajectories) -> dict:
    """The floor of ``task`` against its manifest ``entry`` and demonstration records."""
    floor = FLOORS[task]
    mean = entry["expert_return"]["mean"]
    row = {"task": task, "floor": floor, "expert return": mean,
           "expert std": entry["expert_return"]["std"], "method": entry["expert"]["name"]}
    ok = mean >= floor
    detail = []
    names = list(entry["demo_mode_shares"])
    if len(names) > 1:
        returns = np.array([t.ret for t in trajectories])
        modes = np.array([t.mode for t in trajectories])
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


def report(directory=None) -> list[dict]:
    """:func:`check` for every task with shipped demonstrations, in the tasks' order."""
    from dc_lesson import data
    from dc_lesson import tasks as _tasks
    manifest = data.read_manifest(directory)["tasks"]
    rows = []
    for task in _tasks.NAMES:
        if task in manifest:
            demos = data.load_demos(task, directory=directory)
            rows.append(check(task, manifest[task], demos.trajectories))
        else:
            rows.append({"task": task, "floor": FLOORS[task], "meets floor": False,
                         "method": "no demonstrations yet"})
    return rows
