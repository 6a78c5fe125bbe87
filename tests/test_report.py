"""The rules that turn stored numbers into the book's words (``experiments.report``)."""

import pytest

from dc_lesson.experiments import report


def test_trend_names_each_shape_and_a_single_reversal_breaks_a_trend():
    assert report.trend([0.1, 0.2, 0.5, 0.9]) == "rises at every step"
    assert report.trend([0.9, 0.5, 0.2, 0.1]) == "falls at every step"
    assert report.trend([0.1, 0.5, 0.4, 0.9]) == "has no steady trend"
    assert report.trend([0.5, 0.5]) == "has no steady trend"   # a tie is no rise


def test_trend_refuses_a_single_value():
    with pytest.raises(ValueError, match="at least two"):
        report.trend([0.3])


def test_fmt_drops_an_interval_that_is_not_there():
    assert report.fmt(0.5, 0.4, 0.6, 2) == "0.50 [0.40, 0.60]"
    assert report.fmt(0.5, None, None, 2) == "0.50"
    assert report.fmt(0.5, float("nan"), 0.6, 2) == "0.50"


def test_fmt_never_prints_a_nonzero_mean_as_zero():
    # issue 40: "-0.000 [-0.000, -0.000] ... contradicted" read as no difference at all
    assert report.fmt(-1e-4, -2e-4, -1e-5, 3) == "-1.0e-04"
    assert report.fmt(-1e-4, -0.02, 0.01, 2) == "-1.0e-04 [-0.02, 0.01]"
    assert report.fmt(0.0, -0.02, 0.01, 2) == "0.00 [-0.02, 0.01]"


def test_fmt_shows_no_degenerate_range():
    assert report.fmt(1.1, 1.1, 1.1, 2) == "1.10"             # every seed the same
    assert report.fmt(1.1, 1.0999, 1.1001, 2) == "1.10"       # a range that rounds to a point
    assert report.fmt(1.1, 1.0999, 1.1001, 4) == "1.1000 [1.0999, 1.1001]"


def test_fmt_entry_prints_the_t_interval_the_verdict_rule_reads():
    from dc_lesson.experiments import verdicts
    diffs = [0.3, -0.1, 0.2, 0.25, 0.05]
    t = verdicts.paired_t(diffs)
    paired = {"scaled_return": {"mean": 0.14, "lo": 0.0, "hi": 0.3}, "scaled_return_diffs": diffs}
    assert report.fmt_entry(paired, "scaled_return", 3) == \
        f"{t.mean:.3f} [{t.lo:.3f}, {t.hi:.3f}]"             # not the stored bootstrap band
    row = {"emd_mean": 0.14, "emd_lo": 0.0, "emd_hi": 0.3, "emd_values": diffs}
    assert report.band(row, "emd") == pytest.approx((t.mean, t.lo, t.hi))
    assert report.fmt_entry({"emd_mean": 0.2, "emd_lo": 0.1, "emd_hi": 0.3}, "emd") == \
        "0.20 [0.10, 0.30]"                                    # no per-seed values: stored


def test_a_live_result_carries_its_budget():
    from dc_lesson import budget
    assert report.live_tag(budget.get("smoke")) == "smoke budget: numbers meaningless"
    assert report.live_tag(budget.get("lesson")) == "lesson budget"


def test_favourites_say_agreement_or_count_each_mode_most_first():
    assert report.favourites(["red", "red", "red"]) == "every seed favours red"
    assert report.favourites(["blue"]) == "its one seed favours blue"
    assert report.favourites(["red", "blue", "red", "green"]) == \
        "the favourite differs between seeds: red (2), blue (1), green (1)"
    with pytest.raises(ValueError):
        report.favourites([])


def test_an_interval_of_a_bounded_measure_is_printed_inside_its_limits():
    """A t interval is symmetric about the mean, so a mode TV near 1 can reach past 1: the
    printed interval is clipped to the measure's limits, the rule's interval is not."""
    from dc_lesson.experiments import verdicts
    tv = [0.97, 0.99, 1.0, 1.0, 1.0]
    m, lo, hi = report.t_interval(tv)
    assert hi > 1.0                                              # what the rule computes
    assert report.fmt_entry({"mode_tv_values": tv}, "mode_tv") == f"{m:.2f} [{lo:.2f}, 1.00]"
    assert report.fmt(0.01, -0.02, 0.04, 2, report.bounds("largest_share")) == \
        "0.01 [0.00, 0.04]"
    assert report.fmt_entry({"emd_values": [0.001, 0.0, 0.002, 0.0, 0.03]}, "emd", 3) \
        .endswith("[0.000, 0.023]")                               # an EMD is never negative
    # a difference of two shares lies in [-1, 1]: clipped there, not at 0
    d = [-0.97, -0.99, -1.0, -1.0, -1.0]
    assert report.fmt_entry({"a": "dc", "b": "bc", "mode_tv_diffs": d}, "mode_tv") \
        .startswith("-0.99 [-1.00, ")
    assert report.bounds("mode_tv", difference=True) == (-1.0, 1.0)
    # unbounded measures are printed as computed
    r = [1.1, 0.9, 1.3, 1.2, 0.8]
    t = verdicts.paired_t(r)
    assert report.fmt_entry({"scaled_return_values": r}, "scaled_return", 3) == \
        f"{t.mean:.3f} [{t.lo:.3f}, {t.hi:.3f}]" and t.hi > 1
    assert report.bounds("scaled_return") is None and report.bounds("kl") is None
    # the word is decided on the unclipped interval: clipping changes no verdict
    assert verdicts.word_of_diffs(d, "mode_tv", -1) == verdicts.REPRODUCED
    assert report.clip(-0.2, 0.5, (0.0, 1.0)) == (0.0, 0.5) and \
        report.clip(0.2, 0.5, None) == (0.2, 0.5)
