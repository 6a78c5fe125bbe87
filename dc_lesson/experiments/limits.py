"""The limits a measure's values cannot leave, and intervals clipped to them for display.

Both :mod:`dc_lesson.experiments.report` (numbers in prose and tables) and
:mod:`dc_lesson.experiments.verdicts` (a verdict's evidence) print intervals; the words are
always decided on the interval as computed, so clipping is for the reader's eye only.
"""

from __future__ import annotations

INF = float("inf")
# Below this a printed value is float rounding (the mean of +0.5 and -0.5 can come out
# 5.6e-17), not a measurement: no measure of this book means anything at that size.
NOISE = 1e-9
# Measures whose values cannot leave known limits (a t interval, symmetric about the mean, can:
# a mode TV of 0.99 over seeds may print "0.99 [0.98, 1.01]").  Shares of episodes and total
# variation distances lie in [0, 1]; an EMD and a spread over checkpoints are never negative.
# The scaled return is unbounded (a learner can do worse than random or better than the
# expert), and so are the KL and RKL *estimates* (the expert-vs-expert KL can be below zero).
BOUNDS = {"mode_tv": (0.0, 1.0), "tv": (0.0, 1.0), "largest_share": (0.0, 1.0),
          "beyond_largest": (0.0, 1.0),
          "collapsed_share": (0.0, 1.0), "share": (0.0, 1.0), "probability": (0.0, 1.0),
          "emd": (0.0, INF), "late_spread": (0.0, INF), "curve_spread": (0.0, INF)}


def bounds(measure: str, difference: bool = False) -> tuple[float, float] | None:
    """The limits of ``measure`` (:data:`BOUNDS`), or of a difference of two of its values
    (``difference``: ``[lo - hi, hi - lo]``, e.g. ``[-1, 1]`` for a mode TV); None when the
    measure has none."""
    b = BOUNDS.get(measure)
    if b is None:
        return None
    return (b[0] - b[1], b[1] - b[0]) if difference else b


def clip(lo: float | None, hi: float | None, limits: tuple[float, float] | None):
    """``(lo, hi)`` clipped to ``limits`` (unchanged without limits or without an interval).
    For display only: the verdict rule decides on the unclipped interval
    (:func:`verdicts.paired_t`), and clipping moves no end that lies inside the limits."""
    if limits is None or lo is None or hi is None:
        return lo, hi
    return min(max(lo, limits[0]), limits[1]), max(min(hi, limits[1]), limits[0])


__all__ = ["BOUNDS", "INF", "NOISE", "bounds", "clip"]
