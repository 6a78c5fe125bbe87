"""Figures the book shows: galleries of task frames (and, in later chapters, mode-coverage KDE
plots and learning curves).  Every function returns a matplotlib Figure and saves it when given
a path, so the command line and the notebooks draw the same pictures."""

from __future__ import annotations

import math
import pathlib

import numpy as np


def _save(fig, path):
    if path is not None:
        path = pathlib.Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110, bbox_inches="tight")
    return fig


def gallery(images: list[np.ndarray], titles: list[str], ncols: int = 5, size: float = 2.6,
            path=None):
    """A grid of images with titles (for example one frame per task)."""
    import matplotlib.pyplot as plt
    nrows = math.ceil(len(images) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(size * ncols, size * 0.8 * nrows),
                             squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, img, title in zip(axes.ravel(), images, titles):
        ax.imshow(img)
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def return_bars(names: list[str], means, stds, title: str = "", path=None):
    """Mean return per task with a std error bar, on dm_control's 0..1000 scale."""
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.bar(names, means, yerr=stds, color="#8da0cb", capsize=3)
    ax.set_ylabel("return (0..1000)")
    ax.set_ylim(0, 1000)
    ax.set_title(title)
    ax.tick_params(axis="x", rotation=30)
    fig.tight_layout()
    return _save(fig, path)


# -- state coverage, learning curves, drift (chapter 1 on) ---------------------------------------

REACHER_LIMIT = 0.26   # axis half-width (m) of the reacher coverage maps: the arm reaches 0.24


def _colours(names) -> dict:
    """One colour per name: the expert black, the others seaborn's default palette in order."""
    import seaborn as sns
    palette = iter(sns.color_palette("tab10", max(1, len(names))))
    return {n: "black" if str(n).lower() == "expert" else next(palette) for n in names}


def _named_arrays(what: str, arrays: dict) -> list:
    if not isinstance(arrays, dict) or not arrays:
        raise ValueError(f"{what} must be a non-empty dict of name -> array")
    return list(arrays)


def _features(name: str, x, k: int) -> np.ndarray:
    """A policy's mode-feature sample as (n, k) floats; a 1-D array is read as (n, 1)."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1 and k == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[1] != k or len(a) == 0:
        raise ValueError(f"features of {name!r} must be a non-empty array (n, {k}), got shape "
                         f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"features of {name!r} contain NaN or inf")
    return a


def _band(values, band: str):
    """(centre, low, high) over the first axis: the mean and mean +- one std (``"std"``), the
    mean and the range over runs (``"minmax"``), or the median and the interquartile range
    (``"iqr"``, for skewed quantities such as distances); NaNs (a point a run did not reach)
    are left out."""
    import warnings
    if band not in ("std", "minmax", "iqr"):
        raise ValueError(f"band must be 'std', 'minmax' or 'iqr', got {band!r}")
    with warnings.catch_warnings():   # an all-NaN column is a gap in the line, not an error
        warnings.simplefilter("ignore", RuntimeWarning)
        if band == "iqr":
            lo, mid, hi = np.nanpercentile(values, [25, 50, 75], axis=0)
            return mid, lo, hi
        mean = np.nanmean(values, axis=0)
        if band == "std":
            std = np.nanstd(values, axis=0)
            return mean, mean - std, mean + std
        return mean, np.nanmin(values, axis=0), np.nanmax(values, axis=0)


def coverage_reacher(features_by_name: dict, n_targets: int, bins: int = 104,
                     smooth: float = 1.5, gamma: float = 0.4, size: float = 3.0,
                     cmap: str = "Greys", path=None):
    """The paper's Figure 1: where each policy's fingertip goes, one heat map per policy.

    ``features_by_name`` maps a policy's name ("expert", "BC", ...) to its fingertip x-y
    positions (n, 2), e.g. a ``Demonstrations.mode_features``.  Each map is a 2-D histogram on
    ``bins`` x ``bins`` cells over -0.26..0.26 m, smoothed by a Gaussian of ``smooth`` cells (a
    kernel density estimate on a grid, fast for any number of states), normalised per panel and
    drawn with a power-law colour scale (``gamma`` < 1) so that the paths between targets stay
    visible beside the resting points.  The targets are circles in their colours and true size,
    the arm's reach a dashed circle; all panels share limits and an equal aspect.
    """
    import matplotlib.pyplot as plt
    from matplotlib import colors, patches
    from scipy.ndimage import gaussian_filter

    from dc_lesson.tasks import reacher
    names = _named_arrays("features_by_name", features_by_name)
    if n_targets not in reacher.ANGLES:
        raise ValueError(f"n_targets must be one of {sorted(reacher.ANGLES)}, got {n_targets}")
    lim = REACHER_LIMIT
    edges = np.linspace(-lim, lim, bins + 1)
    fig, axes = plt.subplots(1, len(names), figsize=(size * len(names), size + 0.3),
                             squeeze=False, sharex=True, sharey=True)
    for ax, name in zip(axes[0], names):
        f = _features(name, features_by_name[name], 2)
        h, _, _ = np.histogram2d(f[:, 0], f[:, 1], bins=[edges, edges])
        h = gaussian_filter(h, smooth)
        h = h / h.max() if h.max() > 0 else h
        ax.imshow(h.T, origin="lower", extent=(-lim, lim, -lim, lim), cmap=cmap,
                  norm=colors.PowerNorm(gamma, vmin=0, vmax=1), interpolation="bilinear")
        for (x, y), c in zip(reacher.target_positions(n_targets),
                             reacher.target_colours(n_targets)):
            ax.add_patch(patches.Circle((x, y), reacher.TARGET_SIZE, fill=False, edgecolor=c,
                                        linewidth=2))
        ax.add_patch(patches.Circle((0, 0), 0.24, fill=False, edgecolor="0.6", linewidth=0.8,
                                    linestyle="--"))
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("fingertip x (m)")
    axes[0, 0].set_ylabel("fingertip y (m)")
    fig.tight_layout()
    return _save(fig, path)


def coverage_velocity(features_by_name: dict, bw_adjust: float = 1.0,
                      xlabel: str = "forward velocity (m/s)", title: str = "", path=None):
    """The paper's Figure 7: the density of forward velocity under several policies, as kernel
    density estimates (seaborn, Scott's bandwidth times ``bw_adjust``) on one axis, the expert
    in black.  ``features_by_name`` maps names to velocities, (n, 1) or (n,)."""
    import matplotlib.pyplot as plt
    import seaborn as sns
    names = _named_arrays("features_by_name", features_by_name)
    colour = _colours(names)
    fig, ax = plt.subplots(figsize=(6.5, 3.2))
    for name in names:
        v = _features(name, features_by_name[name], 1)[:, 0]
        expert = str(name).lower() == "expert"
        sns.kdeplot(x=v, ax=ax, label=name, color=colour[name], bw_adjust=bw_adjust,
                    linewidth=2.2 if expert else 1.6, warn_singular=False)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("density")
    ax.set_title(title)
    ax.legend(frameon=False)
    fig.tight_layout()
    return _save(fig, path)


def learning_curves(curves: dict, x, band: str = "std", xlabel: str = "environment steps",
                    ylabel: str = "return", title: str = "", path=None):
    """Mean over seeds with a band, one line per method.

    ``curves`` maps a method's name to an array (n_seeds, n_points) measured at ``x``
    (n_points); a 1-D array is one seed.  The band is mean +- one standard deviation over
    seeds (``band="std"``), the seeds' range (``"minmax"``, better with 2 or 3 seeds), or the
    median and interquartile range (``"iqr"``); NaN entries are skipped.
    """
    import matplotlib.pyplot as plt
    names = _named_arrays("curves", curves)
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or len(x) == 0:
        raise ValueError(f"x must be a non-empty 1-D array, got shape {x.shape}")
    colour = _colours(names)
    fig, ax = plt.subplots(figsize=(6.5, 3.5))
    for name in names:
        y = np.atleast_2d(np.asarray(curves[name], dtype=np.float64))
        if y.ndim != 2 or y.shape[1] != len(x):
            raise ValueError(f"curves[{name!r}] must have shape (n_seeds, {len(x)}), got "
                             f"{np.shape(curves[name])}")
        mean, lo, hi = _band(y, band)
        ax.plot(x, mean, color=colour[name], label=f"{name} ({len(y)} seed"
                f"{'s' if len(y) > 1 else ''})")
        ax.fill_between(x, lo, hi, color=colour[name], alpha=0.2, linewidth=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(frameon=False)
    fig.tight_layout()
    return _save(fig, path)


def drift_plot(distances_by_name, band: str = "std", logy: bool = False,
               ylabel: str = "distance to nearest expert state (std units)",
               title: str = "", path=None):
    """Compounding error: the distance from the policy's state to the nearest expert state
    against the time step, mean and band over episodes: mean +- one std (``band="std"``), the
    range (``"minmax"``), or the median and interquartile range (``"iqr"``, the better choice
    with ``logy``, as distances are skewed and a std band dips below zero).

    ``distances_by_name`` maps a name to the (n_episodes, T + 1) array of
    :func:`dc_lesson.evaluation.metrics.distance_to_expert` (a bare array is drawn as "learner").  Held-out
    expert episodes, drawn in black as "expert", give the floor a perfect imitator would
    follow.
    """
    import matplotlib.pyplot as plt
    if not isinstance(distances_by_name, dict):
        distances_by_name = {"learner": distances_by_name}
    names = _named_arrays("distances_by_name", distances_by_name)
    colour = _colours(names)
    fig, ax = plt.subplots(figsize=(6.5, 3.5))
    for name in names:
        d = np.asarray(distances_by_name[name], dtype=np.float64)
        if d.ndim != 2 or d.size == 0:
            raise ValueError(f"distances of {name!r} must be an array (n_episodes, T + 1), "
                             f"got shape {d.shape}")
        mean, lo, hi = _band(d, band)
        t = np.arange(d.shape[1])
        ax.plot(t, mean, color=colour[name], label=f"{name} ({len(d)} episodes)")
        ax.fill_between(t, lo, hi, color=colour[name], alpha=0.2, linewidth=0)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel("time step")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(frameon=False)
    fig.tight_layout()
    return _save(fig, path)
