"""The headroom study (issue 41, item 1): its grid at each budget, and how its aggregate turns
cells into rows and the headroom rule, on constructed records."""

import math

import pytest

from dc_lesson import budget
from dc_lesson.experiments import studies
from dc_lesson.experiments.studies import headroom


@pytest.mark.parametrize("name, seeds, episodes", [("smoke", 1, 2), ("lesson", 3, 20)])
def test_the_grid_is_task_by_protocol_by_count_by_seed(name, seeds, episodes):
    b = budget.get(name)
    grid = studies.get("headroom").grid(b)
    per_task = (len(headroom.PROTOCOLS) - 1) * len(headroom.COUNTS) + 4   # the diagnostic: 4
    assert len(grid) == len(headroom.TASKS) * per_task * seeds
    assert {c.task for c in grid} == set(headroom.TASKS)
    assert {c.n_demos for c in grid} == set(headroom.COUNTS)
    assert {c.n_demos for c in grid if c.variant == "subsampled-libcap"} == {1, 4, 11, 25}
    assert {c.variant for c in grid} == {"subsampled", "full", "subsampled-libcap"}
    assert {c.seed for c in grid} == set(range(seeds))
    for c in grid:
        cfg = c.config
        assert cfg["eval_episodes"] == episodes and cfg["eval_seed"] == headroom.EVAL_SEED
        assert cfg["subsample_every"] == (None if c.variant == "full" else 20)
        cap = b.bc_max_epochs * (20 if c.variant == "subsampled" else 1)
        assert cfg["bc"]["epochs"] == cap
        assert cfg["bc"]["val_fraction"] == (0.0 if c.n_demos == 1 else 0.3)
        assert not c.needs   # no reference: returns only
    assert len({c.name for c in grid if c.task == "hopper"}) == len(grid) // 7


def _record(task, proto, n, seed, score, best_epoch=10, cap=200):
    return {"cell": {"task": task, "variant": proto, "n_demos": n, "seed": seed,
                     "learner": "bc"},
            "config": {"bc": {"epochs": cap}},
            "result": {"scaled_return": score, "train_pairs": 50 * n, "gradient_steps": 100,
                       "train_mse": 0.01, "best_epoch": best_epoch},
            "provenance": {"wall_seconds": 2.0}}


def test_the_aggregate_gives_a_t_interval_per_row_and_the_rule_per_protocol():
    fewest = [0.5, 0.55, 0.6]
    most = [0.9, 0.95, 0.85]
    recs = [_record("hopper", "subsampled", 1, s, v, best_epoch=200) for s, v in
            enumerate(fewest)]
    recs += [_record("hopper", "subsampled", 25, s, v) for s, v in enumerate(most)]
    recs += [_record("hopper", "full", n, s, 1.0) for n in (1, 25) for s in range(3)]
    recs += [_record("walker", "full", 1, 0, 0.5)]   # one count only: no rule
    out = headroom.aggregate(recs, budget.get("lesson"))
    rows = {(r["task"], r["protocol"], r["n_demos"]): r for r in out["table"]}
    r = rows[("hopper", "subsampled", 1)]
    assert r["scaled_return_values"] == fewest and r["seeds"] == [0, 1, 2]
    # mean 0.55, sd 0.05, t(0.975, 2) = 4.303: half-width 4.303 * 0.05 / sqrt(3)
    assert r["scaled_return_mean"] == pytest.approx(0.55)
    assert r["scaled_return_hi"] - 0.55 == pytest.approx(4.3027 * 0.05 / math.sqrt(3), rel=1e-3)
    assert r["at_cap"] == 3 and rows[("hopper", "subsampled", 25)]["at_cap"] == 0
    assert [k[:2] for k in rows][:2] == [("hopper", "subsampled")] * 2   # protocol order
    rule = {(v["task"], v["protocol"]): v for v in out["headroom"]}
    assert set(rule) == {("hopper", "subsampled"), ("hopper", "full")}
    sub = rule[("hopper", "subsampled")]
    assert (sub["fewest"], sub["most"]) == (1, 25)
    assert sub["in_band"] and sub["rises"] and sub["headroom"]
    assert sub["rise_mean"] == pytest.approx(0.35)
    full = rule[("hopper", "full")]   # at the ceiling: out of band, no rise
    assert not full["in_band"] and full["rises"] is False and full["headroom"] is False


def test_the_rule_needs_the_band_and_a_rise_and_says_nothing_from_one_seed():
    assert headroom.headroom_rule([0.2, 0.25, 0.3], [0.9, 0.9, 0.9])["headroom"] is False
    flat = headroom.headroom_rule([0.5, 0.6, 0.55], [0.5, 0.65, 0.5])
    assert flat["in_band"] and flat["rises"] is False and flat["headroom"] is False
    one = headroom.headroom_rule([0.5], [0.9])
    assert one["rises"] is None and one["headroom"] is None and one["in_band"]
    with pytest.raises(ValueError, match="same seeds"):
        headroom.headroom_rule([0.5, 0.6], [0.9])


def _rows(task, proto, means):
    return [{"task": task, "protocol": proto, "n_demos": n, "scaled_return_mean": m}
            for n, m in means.items()]


def test_the_benchmark_takes_gails_protocol_first_at_the_fewest_count_in_the_band():
    rows = (_rows("hopper", "subsampled", {1: 0.05, 4: 0.2, 11: 0.47, 18: 0.6, 25: 0.9})
            + _rows("hopper", "full", {1: 0.5, 25: 1.0}))
    got = headroom.choose(rows, "hopper")
    # the whole demonstrations are in the band sooner, but GAIL's protocol comes first
    assert (got["protocol"], got["every"], got["counts"]) == ("subsampled", 20, [11, 25])
    assert got["bc"] == {11: 0.47, 25: 0.9} and got["why"] == ""
    walker = (_rows("walker", "subsampled", {1: 0.0, 25: 0.1})
              + _rows("walker", "full", {1: 0.0, 11: 0.47, 25: 0.67}))
    assert headroom.choose(walker, "walker")["protocol"] == "full"
    assert headroom.choose(walker, "walker")["counts"] == [11, 25]
    # at the band's edges: inside counts
    edge = _rows("ant", "subsampled", {4: headroom.BAND[0], 25: 0.9})
    assert headroom.choose(edge, "ant")["counts"] == [4, 25]
    # in the band once, then back below it at a larger count: seed noise, not the start
    noisy = _rows("hopper", "subsampled", {4: 0.19, 6: 0.41, 8: 0.18, 11: 0.47, 25: 0.94})
    assert headroom.choose(noisy, "hopper")["counts"] == [11, 25]


@pytest.mark.parametrize("means, why", [
    ({1: 0.9, 25: 1.0}, "above the band at every count"),
    ({1: 0.0, 25: 0.1}, "below the band at every count"),
    ({4: 0.2, 6: 0.8, 25: 0.9}, "passes the band between two neighbouring counts"),
    ({4: 0.5, 6: 0.2, 25: 0.3}, "falls back below it at a larger count")])
def test_a_task_without_a_count_in_the_band_says_where_bc_is(means, why):
    rows = _rows("t", "subsampled", means) + _rows("t", "full", means)
    got = headroom.choose(rows, "t")
    assert got["protocol"] is None and got["counts"] == [] and why in got["why"]
    assert headroom.choose([], "t")["why"] == "no cells yet"
