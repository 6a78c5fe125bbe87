"""Throughput benchmarks: ``dc-lesson perf rollout``.

For each task it times, on one core and with uniformly random actions:

* **raw**: ``mujoco.mj_step`` on the task's own model, ``n_sub_steps`` physics steps per control
  step and nothing else: the ceiling any Python rollout path can reach;
* **dm_control**: ``dm_control.rl.control.Environment.step`` (TimeStep and observation dict);
* **rollout**: :func:`dc_lesson.data.rollout.collect`, the path every algorithm in the library uses
  (observation, reward, mode feature, validated Trajectory records);
* **EnvPool**, where it is installed (an optional extra, ``pip install envpool==1.2.5``, never
  required): the C++ batched environments of the same suite task or Gym model (``ENVPOOL``), as
  many environments as our batch, one thread, synchronous steps, random actions.  EnvPool
  returns observations and rewards only (no trajectory records), so it is the ceiling of a
  batched engine; its episodes end and reset on their own.

and prints control steps per second with the ratios rollout / raw, rollout / dm_control and
rollout / EnvPool.  Ratios, not absolute times, are what carry over between machines.

How it times, and why: each path runs once untimed before the timed runs (the first rollout
of a process pays for imports and first allocations, up to a second, which a short window would
count as stepping); each timed window is ``n_steps`` control steps (the rollout path's is one
batch of episodes, at most the horizon long, as an algorithm collects them); the four paths
run back to back ``repeats`` times and each ratio is the median of the per-repeat ratios.
Windows of a few hundred batched steps (20-50 ms on a one-substep task) move by 20-30%
from one repeat to the next on this machine; use ``--steps 16000`` or more for numbers to
quote (the lesson budget's default).
"""

from __future__ import annotations

import json
import platform
import time

import mujoco
import numpy as np

from dc_lesson import tasks as _tasks
from dc_lesson.data.rollout import RandomPolicy, collect
from dc_lesson.storage import write_result


def _raw_steps_per_s(name: str, n_steps: int) -> float:
    env = _tasks.make(name, seed=0)
    env.reset(seed=0)
    m, d = env.physics.model.ptr, env.physics.data.ptr
    rng = np.random.default_rng(0)
    ctrl = rng.uniform(env.action_low, env.action_high, size=(n_steps, env.spec.act_dim))
    n_sub = env.n_sub_steps
    t0 = time.perf_counter()
    for t in range(n_steps):
        d.ctrl[:] = ctrl[t]
        mujoco.mj_step(m, d, n_sub)
    return n_steps / (time.perf_counter() - t0)


def _dm_control_steps_per_s(name: str, n_steps: int) -> float:
    env = _tasks.load(name, seed=0)
    env.reset()
    rng = np.random.default_rng(0)
    spec = _tasks.spec(name)
    ctrl = rng.uniform(-1, 1, size=(n_steps, spec.act_dim))
    t0 = time.perf_counter()
    for t in range(n_steps):
        ts = env.step(ctrl[t])
        if ts.last():
            env.reset()
    return n_steps / (time.perf_counter() - t0)


# Our task -> EnvPool's environment of the same model (the suite task's XML, or Gym's model
# for our Gym ports), with the keyword that keeps a fallen Gym robot running like ours.
ENVPOOL = {"cartpole": ("CartpoleBalance-v1", {}), "reacher1": ("ReacherEasy-v1", {}),
           "reacher2": ("ReacherEasy-v1", {}), "reacher4": ("ReacherEasy-v1", {}),
           "hopper": ("Hopper-v5", {"terminate_when_unhealthy": False}),
           "walker": ("WalkerWalk-v1", {}), "halfcheetah": ("CheetahRun-v1", {}),
           "halfcheetah2": ("CheetahRun-v1", {}),
           "ant": ("Ant-v5", {"terminate_when_unhealthy": False}),
           "humanoid": ("HumanoidWalk-v1", {})}


def envpool_version() -> str | None:
    """EnvPool's version if it is installed, else None (the benchmark then skips it)."""
    try:
        import envpool
    except ImportError:
        return None
    return envpool.__version__


def _envpool_steps_per_s(name: str, n_steps: int, batch: int) -> float:
    import envpool
    task_id, kwargs = ENVPOOL[name]
    env = envpool.make_gymnasium(task_id, num_envs=batch, batch_size=batch, num_threads=1,
                                 seed=0, **kwargs)
    env.reset()
    space = env.action_space
    steps = max(10, n_steps // batch)
    actions = np.random.default_rng(0).uniform(space.low, space.high,
                                               size=(steps, batch) + space.shape)
    actions = actions.astype(space.dtype)
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return batch * steps / (time.perf_counter() - t0)


def _rollout_steps_per_s(name: str, n_steps: int, batch: int) -> float:
    """Steady state: ``batch`` episodes in lockstep on a VecEnv built beforehand, as an
    algorithm that collects every iteration keeps one."""
    venv = _tasks.load_vec(name, batch)
    steps = max(10, min(_tasks.spec(name).horizon, n_steps // batch))
    t0 = time.perf_counter()
    collect(name, RandomPolicy(name, 0), batch, seed=0, max_steps=steps, progress=False,
            venv=venv)
    return batch * steps / (time.perf_counter() - t0)


def _warm_up(name: str, batch: int, dm_control: bool = True, envpool: bool = False) -> None:
    """Each path once, untimed: imports and first allocations are not stepping."""
    n = 20 * batch
    _raw_steps_per_s(name, n)
    _rollout_steps_per_s(name, n, batch)
    if dm_control:
        _dm_control_steps_per_s(name, n)
    if envpool:
        _envpool_steps_per_s(name, n, batch)


def rollout_benchmark(names=None, n_steps: int = 16000, batch: int = 16,
                      repeats: int = 5) -> list[dict]:
    """Control steps per second for each task, one row per task.

    After an untimed warm-up of each path, the paths are timed back to back, ``repeats``
    times; each ratio is the median of the per-repeat ratios, so a machine whose speed drifts
    between repeats still gives a fair ratio (the throughputs reported are medians too).
    """
    rows = []
    with_envpool = envpool_version() is not None
    for name in names or _tasks.NAMES:
        _warm_up(name, batch, envpool=with_envpool)
        runs = np.array([[_raw_steps_per_s(name, n_steps), _dm_control_steps_per_s(name, n_steps),
                          _rollout_steps_per_s(name, n_steps, batch),
                          _envpool_steps_per_s(name, n_steps, batch) if with_envpool else np.nan]
                         for _ in range(repeats)])
        raw, dm, ours, pool = np.median(runs, axis=0)
        row = {"task": name, "physics steps per control step": _tasks.spec(name).n_sub_steps,
               "raw mj_step (ctrl steps/s)": raw, "dm_control Environment": dm,
               "dc_lesson rollout": ours,
               "rollout / raw": float(np.median(runs[:, 2] / runs[:, 0])),
               "rollout / dm_control": float(np.median(runs[:, 2] / runs[:, 1])),
               "repeats": repeats, "batch": batch}
        if with_envpool:
            row.update({"envpool task": ENVPOOL[name][0], "EnvPool": pool,
                        "rollout / EnvPool": float(np.median(runs[:, 2] / runs[:, 3]))})
        rows.append(row)
    return rows


SWEEP_BATCHES = (1, 4, 8, 16, 32, 64)


def batch_sweep(name: str = "reacher4", batches=SWEEP_BATCHES, n_steps: int = 16000,
                repeats: int = 5) -> list[dict]:
    """Control steps per second of the rollout path against the number of copies stepped in
    lockstep, as a fraction of raw stepping (a one-substep task, where the per-call overhead
    shows most): how many environments a batch needs before its fixed costs (one MuJoCo call,
    one NumPy pass, one policy call per control step) stop mattering."""
    out = []
    for batch in batches:
        _warm_up(name, batch, dm_control=False)
        runs = np.array([[_raw_steps_per_s(name, n_steps),
                          _rollout_steps_per_s(name, n_steps, batch)] for _ in range(repeats)])
        out.append({"task": name, "batch": batch, "dc_lesson rollout": float(np.median(runs[:, 1])),
                    "rollout / raw": float(np.median(runs[:, 1] / runs[:, 0]))})
    return out


def format_rows(rows: list[dict]) -> str:
    pool = any("EnvPool" in r for r in rows)
    head = (f"{'task':<13}{'substeps':>9}{'raw/s':>10}{'dm_control/s':>14}{'rollout/s':>11}"
            f"{'rollout/raw':>13}{'rollout/dm':>12}"
            + (f"{'EnvPool/s':>11}{'rollout/EnvPool':>17}" if pool else ""))
    lines = [head]
    for r in rows:
        lines.append(f"{r['task']:<13}{r['physics steps per control step']:>9}"
                     f"{r['raw mj_step (ctrl steps/s)']:>10.0f}{r['dm_control Environment']:>14.0f}"
                     f"{r['dc_lesson rollout']:>11.0f}{r['rollout / raw']:>13.2f}"
                     f"{r['rollout / dm_control']:>12.2f}"
                     + (f"{r['EnvPool']:>11.0f}{r['rollout / EnvPool']:>17.2f}"
                        if "EnvPool" in r else ""))
    if not pool:
        lines.append("(EnvPool is not installed, so it is not compared: pip install "
                     "envpool==1.2.5, an optional extra)")
    return "\n".join(lines)


def main(names=None, n_steps: int = 16000, out: str | None = None, command: str = "") -> list[dict]:
    rows = rollout_benchmark(names, n_steps)
    print(format_rows(rows))
    sweep_task = next((n for n in (names or _tasks.NAMES) if n.startswith("reacher")), None)
    sweep = batch_sweep(sweep_task, n_steps=n_steps) if sweep_task else []
    if sweep:
        print(f"{sweep_task}, rollout / raw by environments per batch: "
              + ", ".join(f"{r['batch']}: {r['rollout / raw']:.2f}" for r in sweep))
    if out:
        write_result(out, {"benchmark": "rollout", "n_steps": n_steps, "rows": rows,
                           "batch_sweep": sweep, "envpool": envpool_version(),
                           "machine": platform.processor() or platform.machine()},
                     command=command, seeds=[0])
    return rows


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps(main(), indent=1))
