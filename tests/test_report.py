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


def test_favourites_say_agreement_or_count_each_mode_most_first():
    assert report.favourites(["red", "red", "red"]) == "every seed favours red"
    assert report.favourites(["blue"]) == "its one seed favours blue"
    assert report.favourites(["red", "blue", "red", "green"]) == \
        "the favourite differs between seeds: red (2), blue (1), green (1)"
    with pytest.raises(ValueError):
        report.favourites([])
