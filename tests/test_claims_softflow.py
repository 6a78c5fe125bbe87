"""Chapter 03's statements about the ``softflow_fit`` study's cells (``dc-lesson sweep
softflow_fit``; aggregate ``data/results/softflow_fit_cells.json``, read back with their
features by ``studies.softflow_fit.fit_record``), checked against them.  Each test
quotes, in its name or a comment, the sentence of ``book/03_softflow.py`` it guards; where
the chapter renders its numbers, the test checks the rule that renders them on constructed
records instead."""

import numpy as np
import pytest

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


def _run(fit, task, sigma_max=0.1, seed=0):
    return next(r for r in fit["tasks"][task]["runs"]
                if r["sigma_max"] == sigma_max and r["seed"] == seed)


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

def _toy_fit(gaps, peak_cnf=16.0, peak_soft=5.0):
    """A constructed toy record: per noise level the CNF - SoftFlow gap per seed, curves that
    dip at step 200 and climb 3 nats (CNF) or 0.3 (SoftFlow)."""
    levels = sorted(gaps, key=float)
    summary = {sig: {k: {"mean": 1.0, "std": 0.1} for k in levels} for sig in ("0", "0.1")}
    it = [0, 200, 400, 600]
    runs = []
    for seed in range(len(gaps["0"])):
        for sigma, climb in ((0.0, 3.0), (0.1, 0.3)):
            curve = {k: [5.0, 1.0, 1.0 + climb / 2, 1.0 + climb] for k in levels}
            runs.append({"sigma_max": sigma, "seed": seed,
                         "heldout_curve": {"iteration": it, **curve}})
    fit = {"toy": {"summary": summary, "runs": runs,
                   "cnf_minus_softflow": {k: {"per_seed": v} for k, v in gaps.items()}}}
    arrays = {"toy_density_sigma_0": np.full((3, 3), peak_cnf),
              "toy_density_sigma_0.1": np.full((3, 3), peak_soft)}
    return fit, arrays


def test_toy_findings_count_the_seeds_each_density_wins_on():
    fit, arrays = _toy_fit({"0": [-1.0, -0.5, -0.2], "0.02": [0.7, 1.4, 1.0],
                            "0.05": [2.8, 4.4, 3.0]})
    lines = softflow_fit_study.toy_findings(fit, arrays)
    assert "noise std 0.05) SoftFlow wins on every seed" in lines[0]
    assert "from 2.8 to 4.4" in lines[0]
    assert "At noise 0.02 SoftFlow wins on every seed" in lines[1]
    assert "the plain CNF wins on every seed" in lines[2] and "peaks at 16" in lines[2]
    assert "lowest at step 200 to 200 of 600" in lines[3]
    assert "climbs by 3.0 to 3.0 nats" in lines[3] and "at most 0.30" in lines[3]
    # a mixed record says so: no "every seed" where one seed disagrees
    fit, arrays = _toy_fit({"0": [-1.0, 0.5, -0.2], "0.02": [0.7, -1.4, 1.0],
                            "0.05": [-2.8, -4.4, -3.0]})
    lines = softflow_fit_study.toy_findings(fit, arrays)
    assert "SoftFlow wins on none of the 3 seeds" in lines[0]
    assert "SoftFlow wins on 2 of 3 seeds" in lines[1]
    assert "the plain CNF wins on 2 of 3 seeds" in lines[2]


def test_the_stored_toy_renders_and_sigma_max_orders_the_density_off_the_manifold(fit, arrays):
    """The chapter's rendered toy lines come from the stored record, and its typed reading of
    the sweep ("sigma_max sets how far around the data the density reaches") rests on the
    held-out NLL off the circle falling as sigma_max rises, and on SoftFlow being worse than
    the plain CNF exactly on the circle at every level."""
    assert len(softflow_fit_study.toy_findings(fit, arrays)) == 4
    s = fit["toy"]["summary"]
    levels = sorted(s, key=float)
    off = [s[k]["0.05"]["mean"] for k in levels]
    assert off == sorted(off, reverse=True)
    assert all(s[k]["0"]["mean"] > s["0"]["0"]["mean"] for k in levels if float(k) > 0)


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

