"""The demonstrations on disk: ``data/demos/NAME.npz`` (no pickles) and ``manifest.json``.

Every file is checked against the sha256 its manifest records before it is read, and read with
``allow_pickle=False``.  The manifest's file names are confined to the demos folder: a plain
relative name (no absolute path, no ``..``) of a regular file that, with any links followed,
lies inside the folder; a FIFO, a device such as ``/dev/zero`` or a link out of the folder is
refused before it is opened, so a hostile manifest can neither read elsewhere nor hang.
"""

from __future__ import annotations

import io
import numbers
import os
import pathlib

import numpy as np

from dc_lesson import storage as _storage
from dc_lesson.storage import sha256
from dc_lesson import tasks as _tasks
from dc_lesson.data.types import Demonstrations, Trajectory, TrajectoryError

DEMO_FORMAT = 1
DEMOS_DIR = _storage.DATA / "demos"
_ARRAYS = {  # name in the .npz file -> (dtype, number of dimensions)
    "observations": (np.float32, 3), "actions": (np.float32, 3), "rewards": (np.float64, 2),
    "mode_features": (np.float32, 3), "initial_states": (np.float64, 2),
    "seeds": (np.int64, 1), "modes": (np.int64, 1),
}


class DemoError(ValueError):
    """A demonstration file that is missing, corrupted, or not what it claims to be."""


def demo_set(task: str, variant: str | None = None) -> str:
    """The manifest's name of a set of demonstrations: the task, or ``TASK-VARIANT`` for an
    expert variant (``reacher4-coin``: the hidden-coin expert of chapter 04)."""
    _tasks.check_name(task)
    if variant is None:
        return task
    if not (isinstance(variant, str) and variant.isalnum()):
        raise DemoError(f"a demonstration variant is a short name of letters and digits, got "
                        f"{variant!r}")
    return f"{task}-{variant}"


def regenerate_hint(task: str, variant: str | None = None) -> str:
    return (f"regenerate it with: dc-lesson demos --task {task}"
            + (f" --variant {variant}" if variant else ""))


def save_demos(trajectories: list[Trajectory], path) -> str:
    """Writes trajectories of one task to ``path`` (.npz, atomically); returns its sha256."""
    from dc_lesson.storage import atomic_write_bytes
    if not trajectories:
        raise ValueError(f"no trajectories to save to {path}")
    task = trajectories[0].task
    if any(t.task != task for t in trajectories):
        raise ValueError(f"all trajectories in a demonstration file must be of one task; those "
                         f"for {path} are of {sorted({t.task for t in trajectories})}")
    if any(t.subsampled for t in trajectories):
        raise ValueError(f"subsampled demonstrations are a view of whole ones (their kept "
                         f"steps are not stored): save the whole trajectories (t.whole()), "
                         f"not these, to {path}")
    if len({len(t) for t in trajectories}) != 1:
        raise ValueError(f"demonstrations must all have the same length (the horizon); those "
                         f"for {path} have lengths {sorted({len(t) for t in trajectories})}")
    arrays = {
        "observations": np.stack([t.observations for t in trajectories]),
        "actions": np.stack([t.actions for t in trajectories]),
        "rewards": np.stack([t.rewards for t in trajectories]),
        "mode_features": np.stack([t.mode_features for t in trajectories]),
        "initial_states": np.stack([t.initial_state for t in trajectories]),
        "seeds": np.array([t.seed for t in trajectories], dtype=np.int64),
        "modes": np.array([t.mode for t in trajectories], dtype=np.int64),
        "task": np.array(task), "format": np.array(DEMO_FORMAT),
    }
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())
    return sha256(path)


def _check_regular(path: pathlib.Path, hint: str, what: str = "demonstration file") -> None:
    """Refuses anything but a regular file, reading nothing (the library's one guard,
    :func:`dc_lesson.storage.open_regular`: a FIFO does not block it)."""
    try:
        _storage.open_regular(path, what, hint).close()
    except FileNotFoundError:
        raise DemoError(f"{path} is missing; {hint}") from None
    except _storage.NotRegularFileError as e:
        raise DemoError(str(e)) from None
    except OSError as e:
        raise DemoError(f"{path} cannot be read ({e.strerror}); {hint}") from None


def demo_path(entry: dict, task: str, directory=None) -> pathlib.Path:
    """The file a manifest entry names, confined to the demos folder; ``DemoError`` for an
    absolute name, a ``..``, a link out of the folder or anything but a regular file."""
    folder = pathlib.Path(directory or DEMOS_DIR)
    hint = regenerate_hint(task)
    name = entry.get("file") if isinstance(entry, dict) else None
    if not isinstance(name, str) or not name or "\x00" in name:
        raise DemoError(f"the entry for {task!r} in {manifest_path(directory)} names no file "
                        f"({name!r}); {hint}")
    rel = pathlib.PurePosixPath(name)
    if rel.is_absolute() or pathlib.PureWindowsPath(name).is_absolute() or ".." in rel.parts \
            or "\\" in name:
        raise DemoError(f"the manifest's entry for {task!r} names {name!r}: a demonstration "
                        f"file must be a plain name inside {folder}; {hint}")
    path = folder / rel
    resolved, root = path.resolve(), folder.resolve()
    if not resolved.is_relative_to(root):
        raise DemoError(f"{path} leads out of the demos folder (to {resolved}); {hint}")
    _check_regular(resolved, hint)
    return path


def read_demo_file(path, task: str) -> list[Trajectory]:
    """Reads and validates a demonstration file of ``task``; clear errors for bad files."""
    path = pathlib.Path(path)
    hint = regenerate_hint(task)
    _check_regular(path, hint)
    try:
        with np.load(path, allow_pickle=False) as z:
            contents = {k: z[k] for k in z.files}
    except Exception as e:  # zip, CRC or header errors of a damaged file
        raise DemoError(f"{path} is not a readable demonstration file ({type(e).__name__}: "
                        f"{e}); {hint}") from None
    missing = [k for k in (*_ARRAYS, "task", "format") if k not in contents]
    if missing:
        raise DemoError(f"{path} lacks {', '.join(missing)}: not a dc-lesson demonstration "
                        f"file; {hint}")
    if int(contents["format"]) != DEMO_FORMAT:
        raise DemoError(f"{path} has format {int(contents['format'])}, this library reads "
                        f"format {DEMO_FORMAT}; {hint}")
    if str(contents["task"]) != task:
        raise DemoError(f"{path} holds demonstrations of {str(contents['task'])!r}, not of "
                        f"{task!r}; {hint}")
    n = len(contents["seeds"])
    try:
        for k, (dtype, ndim) in _ARRAYS.items():
            a = contents[k]
            if a.dtype != dtype or a.ndim != ndim or len(a) != n:
                raise TrajectoryError(f"{k} has dtype {a.dtype} and shape {a.shape}")
        return [Trajectory(task=task, observations=contents["observations"][i],
                           actions=contents["actions"][i], rewards=contents["rewards"][i],
                           mode_features=contents["mode_features"][i],
                           initial_state=contents["initial_states"][i],
                           seed=int(contents["seeds"][i]), mode=int(contents["modes"][i]))
                for i in range(n)]
    except TrajectoryError as e:
        raise DemoError(f"{path} is inconsistent: {e}; {hint}") from None


def manifest_path(directory=None) -> pathlib.Path:
    return pathlib.Path(directory or DEMOS_DIR) / "manifest.json"


def read_manifest(directory=None) -> dict:
    path = manifest_path(directory)
    if not path.exists():
        return {"format": DEMO_FORMAT, "tasks": {}}
    fix = "regenerate the demonstrations with: dc-lesson demos --task NAME"
    _check_regular(path, fix, "demonstration manifest")
    try:
        manifest = _storage.read_json(path, "demonstration manifest", fix)
    except _storage.UnreadableFileError as e:
        raise DemoError(str(e)) from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("tasks"), dict):
        raise DemoError(f"{path} is not a demonstration manifest (no 'tasks'); {fix}")
    return manifest


def manifest_entry(task: str, directory=None, variant: str | None = None) -> dict:
    name = demo_set(task, variant)
    entry = read_manifest(directory)["tasks"].get(name)
    if entry is None:
        raise DemoError(f"the manifest {manifest_path(directory)} has no demonstrations "
                        f"{name!r}; {regenerate_hint(task, variant)}")
    return entry


def _check_count(name: str, value, minimum: int = 1) -> None:
    """``value`` is None or a whole number >= ``minimum`` (a bool, 2.5 or "3" is refused)."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"load_demos: {name} must be a whole number or None, got "
                        f"{value!r} ({type(value).__name__})")
    if value < minimum:
        raise ValueError(f"load_demos: {name} must be at least {minimum}, got {value}")


def load_demos(task: str, n_trajectories: int | None = None, seed: int | None = None,
               directory=None, variant: str | None = None) -> Demonstrations:
    """The expert demonstrations of ``task``, checked against the manifest's sha256.

    ``n_trajectories`` takes a subset: with ``seed=None`` the first n (so the paper's subsets
    of 4, 11, 18 and 25 are nested), otherwise n drawn without replacement by that seed.
    ``variant`` names another expert's demonstrations of the task (``"coin"``).
    ``n_trajectories`` and ``seed`` must be whole numbers (``True``, ``2.5`` and ``"3"`` are
    refused, not converted): ``n_trajectories`` from 1 to the number stored, ``seed`` from 0.
    """
    _check_count("n_trajectories", n_trajectories)
    _check_count("seed", seed, minimum=0)
    if directory is not None and not isinstance(directory, (str, os.PathLike)):
        raise TypeError(f"directory must be a path (str or pathlib.Path), got "
                        f"{type(directory).__name__}")
    entry = manifest_entry(task, directory, variant)
    path = demo_path(entry, task, directory)
    hint = regenerate_hint(task, variant)
    if not isinstance(entry.get("sha256"), str):
        raise DemoError(f"the entry for {demo_set(task, variant)!r} in "
                        f"{manifest_path(directory)} has no sha256; {hint}")
    digest = sha256(path)
    if digest != entry["sha256"]:
        raise DemoError(f"{path} does not match its sha256 in the manifest (file {digest[:12]}"
                        f"..., manifest {entry['sha256'][:12]}...): it is corrupted or was "
                        f"changed; {hint}")
    trajs = read_demo_file(path, task)
    if n_trajectories is not None:
        n_trajectories = int(n_trajectories)
        if not 1 <= n_trajectories <= len(trajs):
            raise ValueError(f"{task} has {len(trajs)} demonstrations; asked for "
                             f"{n_trajectories}")
        if seed is None:
            idx = np.arange(n_trajectories)
        else:
            idx = np.sort(np.random.default_rng(int(seed)).choice(len(trajs), n_trajectories,
                                                             replace=False))
        trajs = [trajs[i] for i in idx]
    return Demonstrations(task=task, trajectories=tuple(trajs), manifest=entry)
