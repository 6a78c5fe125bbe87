"""What each learner costs: ``python -m dc_lesson.perf.cost --out FILE``.

Every learner of the registry that uses PPO's environments (GAIL, DC, DRIL, PWIL, NDI, GPRIL)
runs on one task (``reacher4`` by default) at its ``lesson`` configuration, cut to about
``steps`` environment interactions (whole iterations), from one BC warm start on the
protocol's demonstrations (its time not counted), on the current thread count.  For each it
reports the run's seconds, split into

* ``loop_seconds``: the iterations (collecting, rewarding, updating; DC's include its
  Algorithm 2 steps, not its flow fits), summed from the log's steps per second;
* ``setup_seconds``: the rest (DRIL's ensemble, NDI's flow, DC's flow fits, refits and the
  learner episodes they sample);

and ``seconds_per_100k``, **extrapolated**: the setup once plus the loop's cost per
interaction times 100,000.  A run of a few iterations at a loaded machine gives rough numbers;
the load average at the start of each run is recorded beside it.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import os
import sys
import time

import torch

from dc_lesson import algorithms, budget, data
from dc_lesson.algorithms import bc
from dc_lesson.nn import fast
from dc_lesson.storage import write_result

LEARNERS = ("gail", "dc", "dril", "pwil", "ndi", "gpril")


def _config(name: str, b, steps: int):
    cfg = algorithms.get(name).preset(b, seed=0)
    if name == "dc":
        return dataclasses.replace(cfg, iterations=max(1, steps // (cfg.loops * cfg.batch_size)))
    try:
        return cfg.with_steps(steps)
    except ValueError:
        # Fewer interactions than the learner's critic warm-up leaves iterations for (GAIL's
        # first value_warmup iterations train the critic only): run the fewest it accepts;
        # the row's env_steps says what ran, and the per-100k figure scales from that.
        return cfg.with_steps((getattr(cfg, "value_warmup", 0) + 1) * cfg.ppo.batch_size)


@fast.on()   # as sweep workers run the learners (dc_lesson.nn.fast)
def learner_costs(task: str = "reacher4", names=LEARNERS, steps: int = 20_000,
                  budget_name: str = "lesson", warm_start_epochs: int | None = None) -> dict:
    """The costs of the module docstring, one row per learner."""
    b = budget.get(budget_name)
    demos = data.load_demos(task, n_trajectories=b.il_demos)
    t0 = time.perf_counter()
    warm = bc.warm_start_policy(demos, seed=0, max_epochs=warm_start_epochs or b.bc_max_epochs)
    warm_seconds = time.perf_counter() - t0
    rows = []
    for name in names:
        cfg = _config(name, b, steps)
        load = os.getloadavg()[0]
        start = time.perf_counter()
        result = algorithms.get(name).train(task, demos, cfg, policy=copy.deepcopy(warm),
                                            progress=False)
        seconds = time.perf_counter() - start
        if name == "dc":
            env_steps = cfg.env_steps(task)
            its = [r for r in result.log if r.get("kind") == "iteration"]
            loop = sum(cfg.batch_size / r["steps_per_second"] for r in its)
        else:
            env_steps = result.log[-1]["steps"]
            per = env_steps / len(result.log)
            loop = sum(per / r["steps_per_second"] for r in result.log)
        rows.append({"learner": name, "env_steps": int(env_steps), "seconds": seconds,
                     "loop_seconds": loop, "setup_seconds": seconds - loop,
                     "seconds_per_100k": (seconds - loop) + loop / env_steps * 1e5,
                     "load_average": load})
        print(json.dumps({k: (round(v, 1) if isinstance(v, float) else v)
                          for k, v in rows[-1].items()}), flush=True)
    return {"task": task, "budget": budget_name, "steps": steps,
            "threads": torch.get_num_threads(),
            "bc_warm_start_seconds": warm_seconds, "rows": rows}


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(prog="python -m dc_lesson.perf.cost", description=__doc__
                                .split("\n")[0])
    p.add_argument("--task", default="reacher4")
    p.add_argument("--steps", type=int, default=20_000)
    p.add_argument("--learners", nargs="*", default=list(LEARNERS))
    p.add_argument("--out", default=None, help="write the result JSON here")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    out = learner_costs(args.task, args.learners, args.steps)
    if args.out:
        write_result(args.out, {"benchmark": "learner_cost", **out},
                     command="python -m dc_lesson.perf.cost " + " ".join(argv or sys.argv[1:]),
                     seeds=[0])
    return out


if __name__ == "__main__":  # pragma: no cover
    main()
