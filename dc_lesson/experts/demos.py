"""Making the demonstrations: ``dc-lesson demos --task NAME``.

For a task it rolls out the task's expert (``dc_lesson.experts.load_expert``) for
``N_DEMOS`` = 25 fixed-horizon episodes (so the paper's subsets of 4, 11, 18 and 25 exist), then
measures the expert and a uniformly random policy over ``N_EVAL`` = 50 further episodes each:
the two ends of the scaled return (expert 1, random 0).  It writes ``data/demos/NAME.npz`` and
the task's entry in ``data/demos/manifest.json``: sha256, returns, mode shares, seeds, horizon,
and the command and git revision that made them.

Seeds: demonstrations use episode seeds from ``DEMO_SEED``, the expert's evaluation from
``EXPERT_EVAL_SEED`` and the random policy's from ``RANDOM_EVAL_SEED``, so the three sets of
episodes start from different initial states.

A planner expert (``dc_lesson.experts.planner``, the variant ``"planner"`` of walker, ant and
humanoid: ``dc-lesson demos --task walker --variant planner``) costs minutes of CPU per
episode, so for it
the expert's return is measured over the 25 demonstrations plus 25 further episodes (50 in
all, as for every task), not over 50 further ones; the manifest says which.  Its episodes are
collected a few at a time, each finished group saved atomically under ``data/demos/partial/``
with a fingerprint of the expert's settings, so an interrupted ``dc-lesson demos`` resumes
where it stopped (and gives the same file as an uninterrupted run: every episode is a
function of its seed alone).
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import time

import numpy as np

from dc_lesson import data, storage
from dc_lesson.data import rollout
from dc_lesson import tasks as _tasks
from dc_lesson.data.modes import mode_shares
from dc_lesson.storage import atomic_write_text, git_revision

N_DEMOS = 25
N_EVAL = 50
DEMO_SEED, EXPERT_EVAL_SEED, RANDOM_EVAL_SEED = 0, 1, 2


def _stats(returns) -> dict:
    r = np.asarray(returns, dtype=np.float64)
    return {"mean": float(r.mean()), "std": float(r.std(ddof=1)), "min": float(r.min()),
            "max": float(r.max()), "n_episodes": int(len(r))}


@contextlib.contextmanager
def _locked(directory):
    """Serialises manifest updates of demos jobs running side by side."""
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / ".manifest.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _resumable_episodes(task: str, partial, stamp, fingerprint: str, seed: int,
                        first: int = 0) -> list:
    """The finished episodes kept in ``partial``, or [] when they cannot be trusted to be
    episodes first, first + 1, ... of ``seed`` by the expert with ``fingerprint``."""
    if not (partial.exists() and stamp.exists()):
        return []
    fix = f"delete it (the episodes it held are collected again by dc-lesson demos --task {task})"
    for f in (stamp, partial):   # a FIFO would block the reads below, a device never end
        storage.open_regular(f, "partial demonstration file", fix).close()
    try:
        info = json.loads(storage.read_text(stamp, "partial demonstration file", fix))
        if not isinstance(info, dict) or info.get("fingerprint") != fingerprint or \
                info.get("seed") != seed or info.get("first", 0) != first:
            return []
        # The stamp names its file by sha256 (older stamps, written just before their file,
        # only by a count the file cannot exceed): a file left by another expert or seed
        # beside a fresh stamp is not taken for this one's.
        if "sha256" in info:
            if data.sha256(partial) != info["sha256"]:
                return []
        done = data.read_demo_file(partial, task)
        if "sha256" not in info and len(done) > int(info.get("episodes", 0)):
            return []
    except (ValueError, data.DemoError):
        return []              # a damaged stamp or partial file: start this set again
    expected = rollout.episode_seeds(seed, first + len(done))[first:]
    if [t.seed for t in done] != [int(s) for s in expected]:
        return []
    return done


def collect_resumable(task: str, policy, n: int, seed: int, partial, fingerprint: str,
                      chunk: int = 1, progress: bool = True, first: int = 0) -> list:
    """``rollout.collect(task, policy, n, seed)``, ``chunk`` episodes at a time, keeping the
    finished ones in ``partial`` (an .npz, written atomically, then named with its sha256 in
    a stamp beside it, ``partial`` with suffix .json) so a rerun continues there.

    ``fingerprint`` must change whenever the policy's actions would: the stored episodes of
    another fingerprint (or seed) are not reused.  With ``first = k`` the episodes are
    k, k + 1, ... of ``seed`` (a second process can take the end of a set)."""
    import pathlib
    partial = pathlib.Path(partial)
    stamp = partial.with_suffix(".json")
    done = _resumable_episodes(task, partial, stamp, fingerprint, seed, first)[:n]
    bar = None
    if progress:
        from dc_lesson import progress as _progress
        bar = _progress.bar(total=n, initial=len(done), desc=f"{task} episodes (seed {seed})",
                   unit="episode")
    while len(done) < n:
        k = min(chunk, n - len(done))
        done += rollout.collect(task, policy, k, seed=seed, first=first + len(done),
                                batch=k, progress=progress)
        partial.parent.mkdir(parents=True, exist_ok=True)
        digest = data.save_demos(done, partial)
        atomic_write_text(stamp, json.dumps({"fingerprint": fingerprint, "seed": seed,
                                             "first": first, "episodes": len(done),
                                             "sha256": digest}) + "\n")
        if bar is not None:
            bar.update(k)
    if bar is not None:
        bar.close()
    return done


STAGES = ("demos", "eval")


def make_demos(task: str, command: str = "", directory=None, n_demos: int = N_DEMOS,
               n_eval: int = N_EVAL, progress: bool = True, stage: str | None = None,
               threads: int | None = None, first: int | None = None,
               variant: str | None = None) -> dict | None:
    """Generates, stores and registers the demonstrations of ``task``; returns its entry.

    For a planner expert the episodes can be collected by processes side by side, each
    returning None: ``stage="demos"``, ``stage="eval"``, and ``stage="eval", first=k`` (the
    evaluation episodes from k on, in a file of their own).  A last call without ``stage``
    joins what they stored (the sequential evaluation file up to k, the other from k on)
    into the file one run would give.  Never run two processes on the same stage and
    ``first``: each rewrites its partial file.  Measured on the ant, two one-thread processes
    made 8.2 control steps/s against 7.0 for one two-thread process.  ``threads`` sets the
    planner's ``mujoco.rollout`` threads (the episodes do not depend on it).
    ``wall_seconds`` in the entry is the time of this call only; episodes resumed from
    partial files were timed by the calls that made them."""
    import dataclasses
    import hashlib
    import pathlib
    from dc_lesson.experts import load_expert
    _tasks.check_name(task)
    if stage is not None and stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}; the stages are: {', '.join(STAGES)}")
    directory = data.DEMOS_DIR if directory is None else directory
    directory = pathlib.Path(directory)
    expert, info = load_expert(task, variant)
    name = data.demo_set(task, variant)
    t0 = time.time()
    planner = info.get("kind") == "planner"
    if stage is not None and not planner:
        raise ValueError(f"{task!r} has no planner expert: its demonstrations take seconds, "
                         f"run `dc-lesson demos --task {task}` without --stage")
    if planner and threads is not None:
        expert = type(expert)(task, dataclasses.replace(expert.config, threads=int(threads)))
    if planner:
        fingerprint = hashlib.sha256(json.dumps([info, _tasks.spec(task).horizon],
                                                sort_keys=True).encode()).hexdigest()
        part = directory / "partial"
        n_more = max(0, n_eval - n_demos)
        if first is not None and (stage != "eval" or not 0 < first < n_more):
            raise ValueError(f"first applies to stage 'eval' and lies in 1..{n_more - 1}, "
                             f"got stage {stage!r}, first {first!r}")
        if stage in (None, "demos"):
            demos = collect_resumable(task, expert, n_demos, DEMO_SEED,
                                      part / f"{name}-demos.npz", fingerprint,
                                      progress=progress)
        if first is not None:
            collect_resumable(task, expert, n_more - first, EXPERT_EVAL_SEED,
                              part / f"{name}-eval-from{first}.npz", fingerprint,
                              progress=progress, first=first)
            return None
        if stage in (None, "eval"):
            # A finished tail (episodes k..end, from a `first=k` process) shortens the
            # sequential part to episodes 0..k-1.
            split, tail = n_more, []
            for f in sorted(part.glob(f"{name}-eval-from*.npz")):
                k = f.stem.rsplit("from", 1)[1]
                if not k.isdigit():
                    continue   # not a file this code wrote
                k = int(k)
                eps = _resumable_episodes(task, f, f.with_suffix(".json"), fingerprint,
                                          EXPERT_EVAL_SEED, k)
                if 0 < k < split and len(eps) == n_more - k:
                    split, tail = k, eps
            more = collect_resumable(task, expert, split, EXPERT_EVAL_SEED,
                                     part / f"{name}-eval.npz", fingerprint,
                                     progress=progress) + tail
        if stage is not None:
            return None
        expert_eval = demos + more
        eval_note = (f"the {n_demos} demonstrations and {len(more)} further episodes "
                     f"(seed {EXPERT_EVAL_SEED}): a planner costs minutes per episode")
    else:
        demos = rollout.collect(task, expert, n_demos, seed=DEMO_SEED, progress=progress)
        expert_eval = rollout.collect(task, expert, n_eval, seed=EXPERT_EVAL_SEED,
                                      progress=progress)
        eval_note = f"{n_eval} episodes beside the demonstrations (seed {EXPERT_EVAL_SEED})"
    random_eval = rollout.collect(task, rollout.RandomPolicy(task, seed=RANDOM_EVAL_SEED), n_eval,
                                  seed=RANDOM_EVAL_SEED, progress=progress)
    path = directory / f"{name}.npz"
    digest = data.save_demos(demos, path)
    spec = _tasks.spec(task)
    entry = {
        "file": path.name, "sha256": digest, "task": task, "variant": variant,
        "n_trajectories": len(demos),
        "horizon": spec.horizon, "obs_dim": spec.obs_dim, "act_dim": spec.act_dim,
        "mode_feature": list(spec.mode_feature_names),
        "expert": info,
        "demo_return": _stats(rollout.returns(demos)),
        "expert_return": _stats(rollout.returns(expert_eval)),
        "expert_return_episodes": eval_note,
        "random_return": _stats(rollout.returns(random_eval)),
        "demo_mode_shares": mode_shares(task, demos),
        "expert_mode_shares": mode_shares(task, expert_eval),
        "seeds": {"demos": DEMO_SEED, "expert_eval": EXPERT_EVAL_SEED,
                  "random_eval": RANDOM_EVAL_SEED, "random_policy": RANDOM_EVAL_SEED},
        "command": command or (f"dc-lesson demos --task {task}"
                               + (f" --variant {variant}" if variant else "")),
        "revision": git_revision(),
        "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "wall_seconds": round(time.time() - t0, 1),
    }
    with _locked(directory):
        manifest = data.read_manifest(directory)
        manifest["format"] = data.DEMO_FORMAT
        manifest["tasks"][name] = entry
        manifest["tasks"] = dict(sorted(
            manifest["tasks"].items(),
            key=lambda kv: (_tasks.NAMES.index(kv[1].get("task", kv[0])), kv[0])))
        atomic_write_text(directory / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    for pattern in (f"{name}-demos.*", f"{name}-eval.*", f"{name}-eval-from*"):
        for leftover in (directory / "partial").glob(pattern):
            leftover.unlink()      # the finished file replaces the partial ones
    return entry
