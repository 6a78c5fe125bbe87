"""Whole learner runs, the code of an earlier revision against today's: ``dc-lesson perf runs``.

``perf learners`` times a fixed small piece of each learner on two paths of *today's* code
(the fast switches off and on), so it measures what the switches buy, not what the code as a
whole gained: changes made on both paths (a cheaper trace, a batch gathered once per epoch)
are invisible to it.  This benchmark answers the plain question instead: how long does a whole
run at the lesson budget take with the code as it was at revision ``--before`` (issue 14 was
filed at ``7445a95``) and with today's, on this machine?

How: ``git archive`` extracts the package of that revision into a cache folder; each run is a
fresh Python process (one thread for torch, OpenMP and MKL) that imports the package from
either tree, builds the learner's lesson preset, trains it on the same demonstrations (the
current data folder, through ``DC_LESSON_DATA``) from the same BC start, and reports the
seconds of ``train`` alone (imports, the BC start and process start-up are outside).  The two
trees alternate which goes first; the table gives medians, the ratio before / today, and
environment steps per second including the updates.  BC runs a fixed 20 epochs (its early
stopping would otherwise stop the two codes at different epochs); the others run their whole
preset, the same work in both trees (the run prints each tree's config and the benchmark
refuses a pair whose configs differ in anything but fields the older code lacks).

DC is the exception, said in its row's ``note``: its flow's numerics became settings with new
defaults on 2026-12-04 (training and reward solver steps 0.5, 3 nodes for the reward's trace,
NumPy's tanh: ``dc.STORED_NUMERICS`` holds the old ones), so today's DC does less arithmetic
for the same interactions; ``perf dc-fit --variant defaults`` checks that it learns the same.
On request, ``dc-stored``: today's code with the stored numerics, against the earlier code's
DC (what the code alone gained).
"""

from __future__ import annotations

import io
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tarfile

from dc_lesson import storage
from dc_lesson.storage import check_writable, write_result

TASKS = ("reacher4",)
LEARNERS = ("bc", "ppo", "gail", "dc")
# On request: today's DC with the flow numerics of the earlier code (dc.STORED_NUMERICS), and
# the paper's other baselines (each from the same BC start as GAIL and DC).
EXTRA = ("dc-stored", "dril", "pwil", "ndi", "gpril")
_WARM = ("gail", "dc", "dril", "pwil", "ndi", "gpril")   # start from the BC warm start
NOTES = {"dc": "today's DC defaults: the flow's solver steps 0.5, 3 reward nodes, NumPy's tanh "
               "(before: 0.25, 4 nodes, torch's tanh); learning kept: perf dc-fit --variant "
               "defaults",
         "dc-stored": "today's code with the earlier flow numerics (dc.STORED_NUMERICS)"}
ISSUE_14 = "7445a95"   # the revision issue 14 was filed against

# Runs in a fresh process, in either tree: only the interface both revisions share.
_SNIPPET = r"""
import contextlib, dataclasses, json, sys, time
import torch
torch.set_num_threads(1)
import dc_lesson
from dc_lesson import algorithms, budget, data
name, task = sys.argv[1], sys.argv[2]
stored = name == "dc-stored"
name = "dc" if stored else name
b = budget.get("lesson")
algo = algorithms.get(name)
cfg = algo.preset(b, 0)
if name == "bc":
    cfg = dataclasses.replace(cfg, epochs=20, patience=10 ** 6)
numerics = getattr(sys.modules[type(cfg).__module__], "STORED_NUMERICS", None)
if stored and numerics:   # code without the settings runs its only DC
    cfg = (cfg.with_flow(**numerics) if hasattr(cfg, "with_flow")   # nested flow settings
           else dataclasses.replace(cfg, **numerics))
demos = data.load_demos(task, n_trajectories=b.il_demos) if algo.uses_demos else None
# today's fast path, as sweep workers run it; older code had it on by default or not at all
try:
    from dc_lesson.nn import fast
    switch = getattr(fast, "on", contextlib.nullcontext)
except ImportError:
    switch = contextlib.nullcontext
start = None
if name in sys.argv[3].split(","):
    with switch():
        start = algorithms.bc.warm_start_policy(demos, 0, max_epochs=b.bc_max_epochs)
t0 = time.perf_counter()
with switch():
    algo.train(task, demos, cfg, policy=start, progress=False)
seconds = time.perf_counter() - t0
# the stored form where the config has one (flat across DC's nesting of its flow settings)
config = (json.loads(cfg.to_json()) if hasattr(cfg, "to_json")
          else json.loads(json.dumps(dataclasses.asdict(cfg), default=str)))
print(json.dumps({"package": dc_lesson.__file__, "seconds": seconds, "config": config}))
"""


class RevisionError(ValueError):
    """A revision that cannot be extracted (not a git checkout, an unknown name)."""


def _repo_root() -> pathlib.Path:
    """The git checkout: the package's own, else the one the command runs in (a snapshot of
    the package, run from inside a clone)."""
    here = pathlib.Path(__file__).resolve().parents[2]
    if (here / ".git").exists():
        return here
    got = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True,
                         text=True)
    if got.returncode != 0:
        raise RevisionError(f"neither {here} nor the current folder is a git checkout: perf "
                            "runs --before extracts an earlier revision with git; run it from "
                            "a clone of the repository")
    return pathlib.Path(got.stdout.strip())


def extract(revision: str) -> pathlib.Path:
    """The package of ``revision`` (a commit or tag), extracted once into a cache folder;
    returns the folder to put on ``PYTHONPATH``."""
    root = _repo_root()
    got = subprocess.run(["git", "-C", str(root), "rev-parse", "--verify", "--quiet",
                          f"{revision}^{{commit}}"], capture_output=True, text=True)
    if got.returncode != 0:
        raise RevisionError(f"git knows no revision {revision!r} in {root}; give a commit "
                            f"(for example {ISSUE_14}, the revision issue 14 was filed at)")
    sha = got.stdout.strip()
    tree = pathlib.Path(os.environ.get("XDG_CACHE_HOME", pathlib.Path.home() / ".cache")
                        ) / "dc_lesson" / "revisions" / sha
    if not tree.exists():
        archive = subprocess.run(["git", "-C", str(root), "archive", sha, "dc_lesson"],
                                 capture_output=True, check=True).stdout
        # extracted beside, then renamed: an interrupted extraction never looks finished
        partial = tree.with_name(f"{sha}.partial-{os.getpid()}")
        partial.mkdir(parents=True, exist_ok=True)
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(partial, filter="data")
        try:
            partial.rename(tree)
        except OSError:          # another process finished first: use its tree
            if not tree.exists():
                raise
            shutil.rmtree(partial, ignore_errors=True)
    return tree


def run_in(tree: pathlib.Path, learner: str, task: str) -> dict:
    """One timed run of ``learner`` with the package found in ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree), "DC_LESSON_DATA": str(storage.data_root()),
           "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "DC_LESSON_BUDGET": "lesson",
           "PYTHONWARNINGS": "ignore"}
    env.setdefault("MUJOCO_GL", "egl")
    done = subprocess.run([sys.executable, "-c", _SNIPPET, learner, task, ",".join(_WARM)],
                          cwd=str(tree),
                          env=env, capture_output=True, text=True)
    if done.returncode != 0:
        tail = done.stderr.strip().splitlines()[-1:] or ["(no output)"]
        raise RuntimeError(f"{learner} on {task} failed in {tree}: {tail[0]}")
    out = json.loads(done.stdout.strip().splitlines()[-1])
    if not pathlib.Path(out["package"]).resolve().is_relative_to(tree.resolve()):
        raise RuntimeError(f"the run imported {out['package']}, not the package in {tree}: "
                           "an installed copy shadows PYTHONPATH")
    return out


def same_work(before: dict, now: dict) -> list[str]:
    """Fields set differently in the two configs (fields only today's code has are skipped:
    the older code ran without them)."""
    diffs = []

    def walk(a, b, path):
        if isinstance(a, dict) and isinstance(b, dict):
            for k in a:
                if k in b:
                    walk(a[k], b[k], f"{path}{k}.")
            return
        if a != b:
            diffs.append(f"{path[:-1]}: {a!r} before, {b!r} today")
    walk(before, now, "")
    return diffs


def benchmark(before: str = ISSUE_14, tasks=TASKS, learners=LEARNERS, repeats: int = 2,
              log=print) -> list[dict]:
    from dc_lesson import algorithms, budget
    unknown = [n for n in learners if n not in LEARNERS + EXTRA]
    if unknown:
        raise ValueError(f"perf runs times {', '.join(LEARNERS + EXTRA)}; not "
                         f"{', '.join(unknown)}")
    old_tree, new_tree = extract(before), pathlib.Path(__file__).resolve().parents[2]
    b = budget.get("lesson")
    rows = []
    for task in tasks:
        for name in learners:
            runs = {"before": [], "today": []}
            for r in range(repeats):
                for which in (("before", "today") if r % 2 == 0 else ("today", "before")):
                    runs[which].append(run_in(old_tree if which == "before" else new_tree,
                                              name, task))
            diffs = same_work(runs["before"][0]["config"], runs["today"][0]["config"])
            if diffs:
                raise RuntimeError(f"{name} on {task} does different work in the two trees: "
                                   + "; ".join(diffs))
            kind = "dc" if name == "dc-stored" else name
            cfg = algorithms.get(kind).preset(b, 0)
            steps = _env_steps(kind, cfg, task)
            sec = {k: [x["seconds"] for x in v] for k, v in runs.items()}
            med = {k: statistics.median(v) for k, v in sec.items()}
            row = {"learner": name, "task": task, "env_steps": steps,
                   "seconds_before": med["before"], "seconds_today": med["today"],
                   "ratio": statistics.median(o / n for o, n in zip(sec["before"],
                                                                   sec["today"])),
                   "steps_per_s_before": steps / med["before"] if steps else None,
                   "steps_per_s_today": steps / med["today"] if steps else None,
                   "runs": sec, "repeats": repeats}
            if name in NOTES:
                row["note"] = NOTES[name]
            rows.append(row)
            log(format_row(row))
    return rows


def _env_steps(kind: str, cfg, task: str) -> int:
    """The interactions a learner's lesson preset takes (BC: none)."""
    if kind == "bc":
        return 0
    if hasattr(cfg, "env_steps"):            # DC: iterations x loops x batch
        return int(cfg.env_steps(task))
    inner = getattr(cfg, "ppo", cfg)         # the RL-based learners carry PPO's settings
    return int(getattr(cfg, "total_steps", 0) or getattr(inner, "total_steps", 0))


def in_words(rows: list[dict]) -> str:
    """A stored benchmark in one line (``HISTORY.md`` says it): the longest run of today's
    code, and whether every learner ran faster than with the earlier code (each ratio above 1)."""
    longest = max(rows, key=lambda r: r["seconds_today"])
    slower = [f"{r['learner']} on {r['task']}" for r in rows if not r["ratio"] > 1]
    return (f"the longest lesson run: {longest['learner']} on {longest['task']}, "
            f"{longest['seconds_today']:.0f} s; "
            + ("every learner ran faster than with the earlier code" if not slower else
               "no faster than with the earlier code: " + ", ".join(slower)))


def format_row(r: dict) -> str:
    sps = (f"  env steps/s {r['steps_per_s_before']:.0f} -> {r['steps_per_s_today']:.0f}"
           if r["env_steps"] else "")
    return (f"{r['learner']:<5} {r['task']:<12} {r['seconds_before']:6.1f} s -> "
            f"{r['seconds_today']:6.1f} s  (x{r['ratio']:.2f}){sps}")


def main(before=None, tasks=None, learners=None, repeats: int = 2, out=None,
         command: str = "") -> list[dict]:
    if out:
        check_writable(out)
    before = before or ISSUE_14
    rows = benchmark(before, tasks or TASKS, learners or LEARNERS, repeats)
    if out:
        commit = subprocess.run(["git", "-C", str(_repo_root()), "rev-parse", before],
                                capture_output=True, text=True).stdout.strip()
        write_result(out, {"benchmark": "runs", "before": before, "before_commit": commit,
                           "rows": rows, "threads": 1}, command=command, seeds=[0])
    return rows


__all__ = ["EXTRA", "ISSUE_14", "LEARNERS", "NOTES", "RevisionError", "TASKS", "benchmark", "extract",
           "format_row", "in_words", "main", "run_in", "same_work"]
