"""The figure check every chapter runs (``viz.legibility.watch``, from ``notebook.start``):
colliding tick labels are found and warned about, legible figures are left alone."""

import warnings

import matplotlib
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt   # noqa: E402

from dc_lesson.viz import legibility   # noqa: E402


def _crowded(width=2.0):
    fig, ax = plt.subplots(figsize=(width, 2))
    ax.set_xticks(range(10), labels=[f"label {i}" for i in range(10)])
    ax.set_title("crowded")
    return fig


def test_colliding_tick_labels_are_named_by_axes_and_label():
    fig = _crowded()
    found = legibility.overlapping_ticks(fig)
    assert found and all(f.startswith("crowded: x labels ") for f in found)
    assert "'label 0' and 'label 1'" in found[0]
    # the same labels on a figure wide enough to hold them: nothing to say
    assert legibility.overlapping_ticks(_crowded(width=14)) == []
    plt.close("all")


def test_labels_outside_the_view_and_hidden_ones_are_not_counted():
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1], [0, 1])
    ax.set_xticks([0, 0.5, 1, 1.001], labels=["0", "0.5", "1", "one"])
    ax.set_xlim(0, 1)   # after the ticks (which widen the view): 1.001 is not drawn
    assert legibility.overlapping_ticks(fig) == []
    fig2 = _crowded()
    for t in fig2.axes[0].get_xticklabels()[1::2]:
        t.set_visible(False)
    assert all("label 1'" not in f for f in legibility.overlapping_ticks(fig2))
    plt.close("all")


def test_watching_warns_when_a_figure_is_drawn_and_only_then():
    legibility.watch()
    legibility.watch()   # twice: still one check per draw
    try:
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            _crowded().canvas.draw()
            fine, ax = plt.subplots(figsize=(4, 3))
            ax.plot([1, 2, 3])
            fine.canvas.draw()
    finally:
        legibility.unwatch()   # the other tests draw with matplotlib's own draw
    overlaps = [w for w in got if issubclass(w.category, legibility.TickLabelOverlap)]
    assert len(overlaps) == 1 and "crowded: x labels" in str(overlaps[0].message)
    with warnings.catch_warnings(record=True) as after:
        warnings.simplefilter("always")
        _crowded().canvas.draw()
    assert not [w for w in after if issubclass(w.category, legibility.TickLabelOverlap)]
    plt.close("all")


@pytest.mark.parametrize("rotation", [0, 90])
def test_rotation_is_seen_as_drawn(rotation):
    fig = _crowded(width=3)
    for t in fig.axes[0].get_xticklabels():
        t.set_rotation(rotation)
    assert bool(legibility.overlapping_ticks(fig)) == (rotation == 0)
    plt.close("all")


def test_a_turned_label_is_its_turned_box_not_its_hull():
    """Chapter 0's bars: labels turned 30 degrees whose axis-aligned hulls overlap while the
    text does not (what a reader sees); packed tighter, the turned text itself collides."""
    from dc_lesson.viz import plots
    names = ["cartpole", "reacher1", "reacher2", "reacher4", "hopper", "walker",
             "halfcheetah", "halfcheetah2", "ant", "humanoid"]
    plots.return_bars(names, [100] * 10, [10] * 10, title="bars")
    fig = plt.gcf()
    labels = fig.axes[0].get_xticklabels()
    r = fig.canvas.get_renderer()
    hulls = [labels[i].get_window_extent(r) for i in (6, 7)]
    assert hulls[0].overlaps(hulls[1])               # the hulls touch...
    assert legibility.overlapping_ticks(fig) == []   # ...the text does not
    tight, ax = plt.subplots(figsize=(1.5, 2))
    ax.set_xticks(range(10), labels=names, rotation=30)
    assert legibility.overlapping_ticks(tight)
    plt.close("all")
