"""Figures a reader can read: tick labels that do not run into each other.

A chapter's figure is drawn once, in the reader's browser, and nobody looks at it again until
a reader does; a label printed over its neighbour ("0.250.500.75") is found late.  So
:func:`watch` (which :func:`dc_lesson.notebook.start` calls) checks every figure as it is
drawn: where two visible tick labels of one axis overlap, it warns, naming the axes and the
labels.  In a chapter the warning is printed under the cell, where the browser checker
(``.ci/browser_check.py``) fails on it as on any warning.

The check uses the drawn text (``Text.get_window_extent``, a rotated label as its turned box),
so it sees what the reader sees at the figure's size and resolution.
"""

from __future__ import annotations

import warnings

import matplotlib.figure
import numpy as np
from matplotlib.text import Text

_PAD = 1.0     # pixels: boxes that merely touch are legible, a shared pixel row is not


class TickLabelOverlap(UserWarning):
    """Two tick labels of one axis overlap in a drawn figure."""


def _drawn_labels(axis, minor: bool):
    """The non-empty, visible tick labels that are drawn: those whose tick lies inside the
    axis's view interval (a locator also returns ticks just outside it, which are not drawn)."""
    lo, hi = sorted(axis.get_view_interval())
    span = (hi - lo) * 1e-9
    return [t for loc, t in zip(axis.get_ticklocs(minor=minor), axis.get_ticklabels(minor=minor))
            if lo - span <= loc <= hi + span and t.get_visible() and t.get_text().strip()]


def _corners(label, renderer) -> np.ndarray:
    """The four corners (pixels) of the label's text as drawn: its unrotated box turned by its
    rotation about the centre of its drawn, axis-aligned box (which is the turned box's
    centre, whatever the alignment), shrunk by :data:`_PAD`."""
    flat = Text(0, 0, label.get_text(), fontproperties=label.get_fontproperties())
    flat.set_figure(label.get_figure())
    size = flat.get_window_extent(renderer)
    w, h = max(size.width - 2 * _PAD, 0.0), max(size.height - 2 * _PAD, 0.0)
    centre = label.get_window_extent(renderer)
    cx, cy = (centre.x0 + centre.x1) / 2, (centre.y0 + centre.y1) / 2
    a = np.deg2rad(label.get_rotation())
    turn = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    half = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2
    return half @ turn.T + [cx, cy]


def _overlap(p: np.ndarray, q: np.ndarray) -> bool:
    """Whether two convex quadrilaterals overlap (separating axis test on their edges)."""
    for poly in (p, q):
        for i in range(4):
            edge = poly[(i + 1) % 4] - poly[i]
            normal = np.array([-edge[1], edge[0]])
            a, b = p @ normal, q @ normal
            if a.max() <= b.min() or b.max() <= a.min():
                return False
    return True


def overlapping_ticks(fig: matplotlib.figure.Figure, renderer=None) -> list[str]:
    """Every pair of visible tick labels of one axis whose drawn text overlaps (rotated labels
    as turned boxes, not their axis-aligned hulls), as ``"<axes title or panel n>: x labels
    '0.25' and '0.50'"``; empty for a legible figure."""
    renderer = renderer or fig.canvas.get_renderer()
    found = []
    for i, ax in enumerate(fig.axes):
        if not ax.get_visible():
            continue
        name = ax.get_title() or f"panel {i + 1}"
        for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            labels = _drawn_labels(axis, False) + _drawn_labels(axis, True)
            boxes = [(_corners(t, renderer), t.get_text()) for t in labels]
            for a in range(len(boxes)):
                for b in range(a + 1, len(boxes)):
                    if _overlap(boxes[a][0], boxes[b][0]):
                        found.append(f"{name}: {which} labels {boxes[a][1]!r} and "
                                     f"{boxes[b][1]!r}")
    return found


_original_draw = None


def watch() -> None:
    """From now on, warn (:class:`TickLabelOverlap`) when a drawn figure has overlapping tick
    labels; calling it again changes nothing."""
    global _original_draw
    if _original_draw is not None:
        return
    _original_draw = matplotlib.figure.Figure.draw

    def draw(self, renderer):
        _original_draw(self, renderer)
        found = overlapping_ticks(self, renderer)
        if found:   # named by this module, not by the matplotlib line that drew it
            warnings.warn_explicit(
                "tick labels overlap in a figure (" + "; ".join(found[:4])
                + (f"; {len(found) - 4} more" if len(found) > 4 else "")
                + "): fewer ticks, a wider figure or rotated labels",
                TickLabelOverlap, filename=__name__, lineno=0)

    matplotlib.figure.Figure.draw = draw


def unwatch() -> None:
    """Stop checking drawn figures (matplotlib's own ``Figure.draw`` again)."""
    global _original_draw
    if _original_draw is not None:
        matplotlib.figure.Figure.draw = _original_draw
        _original_draw = None


__all__ = ["TickLabelOverlap", "overlapping_ticks", "unwatch", "watch"]
