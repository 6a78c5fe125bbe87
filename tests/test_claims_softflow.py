"""Chapter 03's statements about the ``softflow_fit`` study's cells (``dc-lesson sweep
softflow_fit``; aggregate ``data/results/softflow_fit_cells.json``, read back with their
features by ``studies.softflow_fit.fit_record``), checked against them.  Each test
quotes, in its name or a comment, the sentence of ``book/03_softflow.py`` it guards; the
numbers are the ones the chapter prints, rounded as it rounds them."""

import numpy as np
import pytest

from dc_lesson.experiments import softflow as bs
from dc_lesson.experiments.studies import softflow_fit as softflow_fit_study
from dc_lesson.storage import read_result


@pytest.fixture(scope="module")
def stored():
    return softflow_fit_study.fit_record(read_result("softflow_fit_cells.json"))


@pytest.fixture(scope="module")
def fit(stored):
    return stored[0]


@pytest.fixture(scope="module")
def arrays(stored):
    return stored[1]


def _toy_runs(fit, sigma_max):
    return [r for r in fit["toy"]["runs"] if r["sigma_max"] == sigma_max]


def _run(fit, task, sigma_max=0.1, seed=0):
    return next(r for r in fit["tasks"][task]["runs"]
                if r["sigma_max"] == sigma_max and r["seed"] == seed)


def _r(x, digits=2):
    return round(float(x), digits)


# -- provenance ----------------------------------------------------------------------------------

def test_the_stored_run_is_the_lesson_run_the_chapter_describes(fit, arrays):
    assert fit["command"].startswith("dc-lesson aggregate softflow_fit")
    assert fit["budget"] == "lesson" and fit["seeds"] == [0, 1, 2] and fit["threads"] == 1
    assert fit["cells"]["n"] == fit["cells"]["of"]               # the whole study
    sizes = fit["budget_sizes"]
    assert list(sizes["softflow_toy_seeds"]) == [0, 1, 2]
    assert list(sizes["softflow_task_seeds"]) == [0]
    assert list(sizes["softflow_sigma_maxes"]) == [0.0, 0.03, 0.1, 0.3]
    assert fit["toy"]["config"]["iterations"] == 600 and fit["toy"]["train_points"] == 2000
    assert fit["toy"]["config"]["lr"] == 3e-3 and fit["toy"]["config"]["hidden"] == [32, 32]
    for task in ("reacher4", "halfcheetah2"):
        t = fit["tasks"][task]
        assert t["train_states"] == 4000
        assert all(r["config"]["iterations"] == 1000 and r["config"]["hidden"] == [64, 64]
                   for r in t["runs"])
    assert set(arrays) >= {"toy_grid", "toy_density_sigma_0", "toy_density_sigma_0.1",
                           "reacher4_samples_seed0_sigma_0.1",
                           "halfcheetah2_samples_seed0_sigma_0.1"}


# -- the toy -------------------------------------------------------------------------------------

def test_toy_softflow_wins_off_the_circle_on_every_seed(fit):
    s = fit["toy"]["summary"]
    # "at noise std 0.05 its held-out NLL is 0.75 ± 0.14 nats against the plain CNF's 4.28 ± 0.53"
    assert (_r(s["0.1"]["0.05"]["mean"]), _r(s["0.1"]["0.05"]["std"])) == (0.75, 0.14)
    assert (_r(s["0"]["0.05"]["mean"]), _r(s["0"]["0.05"]["std"])) == (4.28, 0.53)
    gap = fit["toy"]["cnf_minus_softflow"]
    # "better by 2.8 to 4.4 nats, depending on the seed"
    assert (_r(min(gap["0.05"]["per_seed"]), 1), _r(max(gap["0.05"]["per_seed"]), 1)) == (2.8, 4.4)
    # "At noise 0.02 it is better by 0.7 to 1.4 nats"
    assert (_r(min(gap["0.02"]["per_seed"]), 1), _r(max(gap["0.02"]["per_seed"]), 1)) == (0.7, 1.4)
    assert len(gap["0.05"]["per_seed"]) == 3


def test_toy_plain_cnf_wins_exactly_on_the_circle_on_every_seed(fit):
    s, gap = fit["toy"]["summary"], fit["toy"]["cnf_minus_softflow"]["0"]["per_seed"]
    assert all(g < 0 for g in gap)
    # "by 0.4 to 1.6 nats (−1.84 ± 0.50 against −0.83 ± 0.10)"
    assert (_r(-max(gap), 1), _r(-min(gap), 1)) == (0.4, 1.6)
    assert (_r(s["0"]["0"]["mean"]), _r(s["0"]["0"]["std"])) == (-1.84, 0.50)
    assert (_r(s["0.1"]["0"]["mean"]), _r(s["0.1"]["0"]["std"])) == (-0.83, 0.10)


def test_toy_plain_cnf_piles_its_mass_onto_the_curve(arrays):
    # "peaks of about 16 against SoftFlow's 5" (the stored seed-0 images)
    assert round(float(arrays["toy_density_sigma_0"].max())) == 16
    assert round(float(arrays["toy_density_sigma_0.1"].max())) == 5


def test_toy_curves_show_the_squeeze(fit):
    for r in _toy_runs(fit, 0.0):
        c = r["heldout_curve"]
        # "The plain CNF's NLL on the circle ends at its lowest"
        assert c["0"][-1] == min(c["0"])
        # "its NLL at noise 0.05 is lowest early (by step 240 on every seed)"
        assert c["iteration"][int(np.argmin(c["0.05"]))] <= 240
    climbs = [r["heldout_curve"]["0.05"][-1] - min(r["heldout_curve"]["0.05"])
              for r in _toy_runs(fit, 0.0)]
    # "and then climbs by 2.2 to 4.2 nats to the end"
    assert (_r(min(climbs), 1), _r(max(climbs), 1)) == (2.2, 4.2)
    # "SoftFlow's NLL at noise 0.05 also turns up late in training, but by less than half a nat"
    for r in _toy_runs(fit, 0.1):
        c = r["heldout_curve"]["0.05"]
        assert 0 < c[-1] - min(c) < 0.5


def test_toy_sigma_max_buys_density_off_the_manifold(fit):
    s = fit["toy"]["summary"]
    off = [s[k]["0.05"]["mean"] for k in ("0", "0.03", "0.1", "0.3")]
    # "falls from 4.28 (plain CNF) to 0.85, 0.75 and 0.45 nats"
    assert [_r(x) for x in off] == [4.28, 0.85, 0.75, 0.45] and off == sorted(off, reverse=True)
    # "On the circle itself every SoftFlow is worse than the plain CNF (−0.64 to −0.83 against
    # −1.84)"
    on = [s[k]["0"]["mean"] for k in ("0.03", "0.1", "0.3")]
    assert all(x > s["0"]["0"]["mean"] for x in on)
    assert (_r(max(on)), _r(min(on))) == (-0.64, -0.83)


# -- the record is the cells' ---------------------------------------------------------------------

def test_the_chapters_record_is_rebuilt_from_the_cells(stored):
    """fit_record gives every toy and task run of the aggregate, each task's facts and the
    arrays the figures draw; its summaries are the cells' own numbers (the aggregate's table
    means), and the task sections' prose renders from it (no typed task numbers)."""
    fit, arrays = stored
    agg = read_result("softflow_fit_cells.json")
    assert len(fit["toy"]["runs"]) + sum(len(t["runs"]) for t in fit["tasks"].values()) == \
        len(agg["runs"])
    table = {(r["task"], r["row"]): r for r in agg["table"]}
    for s, row in fit["toy"]["summary"].items():
        for nz, v in row.items():
            assert v["mean"] == pytest.approx(table[("circle", f"softflow-sigma={s}")]
                                              [f"nll {nz}_mean"])
    for task, t in fit["tasks"].items():
        assert {"kde", "gaussian", "modes", "data_mode_shares"} <= set(t)
        assert arrays[f"{task}_data_features"].shape[0] > 0
        for r in t["runs"]:
            assert f"{task}_samples_seed{r['seed']}_sigma_{r['sigma_max']:g}" in arrays
    assert "feature_kde_samples" in fit["tasks"]["halfcheetah2"]["runs"][0]

