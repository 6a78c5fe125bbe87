"""What the studies share: input errors, evaluation seeds that never replay a demonstration,
and the mode features stored beside a result file (an ``.npz``, no pickles)."""

from __future__ import annotations

import io
import pathlib

import numpy as np

from dc_lesson import data as _data
from dc_lesson.data import rollout as _rollout
from dc_lesson.storage import RESULTS, atomic_write_bytes


class BenchInputError(ValueError):
    """Sizes or seeds the benchmark cannot run with."""


def check_count(name: str, value, minimum: int = 1):
    """``value`` as an int if it is a whole number >= ``minimum``; ``BenchInputError``
    otherwise (a size of 0 or below is refused, never replaced by a default)."""
    import numbers
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise BenchInputError(f"{name} must be a whole number of at least {minimum}, got "
                              f"{value!r}")
    return int(value)


def default(value, fallback):
    """``fallback`` only when ``value`` is None (not when it is 0 or empty: those are errors
    the checks report, not requests for the default)."""
    return fallback if value is None else value


def check_eval_seeds(demos: _data.Demonstrations, eval_seed: int, n: int) -> None:
    """Refuses evaluation seeds whose episodes would start where a demonstration started."""
    clash = set(_rollout.episode_seeds(eval_seed, n).tolist()) & {t.seed for t in
                                                                   demos.trajectories}
    if clash:
        raise BenchInputError(f"evaluation seed {eval_seed} gives {len(clash)} episode(s) that "
                              f"start where a {demos.task} demonstration started; choose "
                              f"another")


def subsample(x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    """At most ``n`` rows of ``x`` (a seeded subsample in order, float32)."""
    x = np.asarray(x, dtype=np.float32)
    if len(x) <= n:
        return x
    return x[np.sort(np.random.default_rng(seed).choice(len(x), n, replace=False))]


def features_path(json_path) -> pathlib.Path:
    """The ``.npz`` of mode features beside a result file."""
    return pathlib.Path(json_path).with_suffix(".npz")


def feature_key(task: str, method: str, seed: int | None = None) -> str:
    return f"{task}__{method}" + ("" if seed is None else f"__seed{seed}")


def save_features(path, arrays: dict) -> pathlib.Path:
    """Writes float32 arrays to ``path`` (an ``.npz``) atomically."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **{k: np.asarray(v, dtype=np.float32) for k, v in arrays.items()})
    atomic_write_bytes(path, buf.getvalue())
    return pathlib.Path(path)


def load_features(json_path_or_name="gail_modes.json") -> dict[str, np.ndarray]:
    """The mode features stored beside a ``bench gail`` result (no pickles)."""
    p = pathlib.Path(json_path_or_name)
    if not p.is_absolute() and not p.exists():
        p = RESULTS / p
    path = features_path(p)
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing; `dc-lesson bench gail --out "
                                f"{p}` writes it beside the result file")
    with np.load(path, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


__all__ = ["BenchInputError", "check_count", "check_eval_seeds", "default", "feature_key", "features_path", "load_features",
           "save_features", "subsample"]
