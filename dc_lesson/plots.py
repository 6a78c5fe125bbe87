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
