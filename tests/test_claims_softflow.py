"""Chapter 03's statements about ``data/results/softflow_fit.json`` (made by ``dc-lesson bench
softflow-fit --out data/results/softflow_fit.json``), checked against the file.  Each test
quotes, in its name or a comment, the sentence of ``book/03_softflow.py`` it guards; the
numbers are the ones the chapter prints, rounded as it rounds them."""

import numpy as np
import pytest

from dc_lesson.experiments import softflow as bs
from dc_lesson.storage import RESULTS, read_result


@pytest.fixture(scope="module")
def fit():
    return read_result("softflow_fit.json")


@pytest.fixture(scope="module")
def arrays():
    return bs.load_fit_arrays(RESULTS / "softflow_fit.json")


def _toy_runs(fit, sigma_max):
    return [r for r in fit["toy"]["runs"] if r["sigma_max"] == sigma_max]


def _run(fit, task, sigma_max=0.1, seed=0):
    return next(r for r in fit["tasks"][task]["runs"]
                if r["sigma_max"] == sigma_max and r["seed"] == seed)


def _r(x, digits=2):
    return round(float(x), digits)


# -- provenance ----------------------------------------------------------------------------------

def test_the_stored_run_is_the_lesson_run_the_chapter_describes(fit, arrays):
    assert fit["command"] == "dc-lesson bench softflow-fit --out data/results/softflow_fit.json"
    assert fit["budget"] == "lesson" and fit["seeds"] == [0, 1, 2] and fit["threads"] == 1
    sizes = fit["budget_sizes"]
    assert sizes["softflow_toy_seeds"] == [0, 1, 2] and sizes["softflow_task_seeds"] == [0]
    assert sizes["softflow_sigma_maxes"] == [0.0, 0.03, 0.1, 0.3]
    assert fit["toy"]["config"]["iterations"] == 600 and fit["toy"]["train_points"] == 2000
    assert fit["toy"]["config"]["lr"] == 3e-3 and fit["toy"]["config"]["hidden"] == [32, 32]
    for task in ("reacher4", "halfcheetah2"):
        t = fit["tasks"][task]
        assert t["train_states"] == 4000
        assert all(r["config"]["iterations"] == 1000 and r["config"]["hidden"] == [64, 64]
                   for r in t["runs"])
    # "It took about 12 minutes on one thread"
    assert round(fit["wall_seconds"] / 60) == 12
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


# -- expert states -------------------------------------------------------------------------------

def test_softflow_fits_held_out_demonstrations_better_than_kde_and_gaussian(fit):
    r4, hc = fit["tasks"]["reacher4"], fit["tasks"]["halfcheetah2"]
    # "held-out NLL −17.6 nats on reacher4 (KDE −6.2, Gaussian 0.8)"
    assert _r(_run(fit, "reacher4")["heldout_nll"]["clean"], 1) == -17.6
    assert _r(r4["kde"]["heldout_nll"]["clean"], 1) == -6.2
    assert _r(r4["gaussian"]["heldout_nll"]["clean"], 1) == 0.8
    # "and 7.6 on halfcheetah2 (KDE 10.5, Gaussian 17.9)"
    assert _r(_run(fit, "halfcheetah2")["heldout_nll"]["clean"], 1) == 7.6
    assert _r(hc["kde"]["heldout_nll"]["clean"], 1) == 10.5
    assert _r(hc["gaussian"]["heldout_nll"]["clean"], 1) == 17.9


def test_neither_task_fit_had_converged(fit):
    # "the held-out NLL was still falling at the last checkpoint (by about 0.9 nats on each
    # over the last 100 steps)"
    for task in ("reacher4", "halfcheetah2"):
        c = _run(fit, task)["heldout_curve"]
        assert c["iteration"][-2:] == [900, 1000]
        assert _r(c["clean"][-2] - c["clean"][-1], 1) == 0.9, task


def test_reacher_states_are_almost_points(fit):
    t = fit["tasks"]["reacher4"]
    # "98% of its training states lie within 2 cm of a target"
    assert t["at_mode_tolerance"] == 0.02 and _r(sum(t["data_at_mode_shares"])) == 0.98


def test_every_mode_gets_high_density(fit):
    r4, run = fit["tasks"]["reacher4"], _run(fit, "reacher4")
    flow = [run["mode_logp"][m] for m in r4["modes"]]
    kde = [r4["kde"]["mode_logp"][m] for m in r4["modes"]]
    # "between 14.7 and 24.0 for SoftFlow (the KDE: 6.2 to 7.9)"
    assert (_r(min(flow), 1), _r(max(flow), 1)) == (14.7, 24.0)
    assert (_r(min(kde), 1), _r(max(kde), 1)) == (6.2, 7.9)
    # "the rarest target (yellow, 5% of the states) included"
    shares = dict(zip(r4["modes"], r4["data_mode_shares"]))
    assert min(shares, key=shares.get) == "yellow" and _r(shares["yellow"]) == 0.05
    assert all(f > k for f, k in zip(flow, kde))
    hc, hrun = fit["tasks"]["halfcheetah2"], _run(fit, "halfcheetah2")
    # "the backward run −2.9 and the forward run −10.4 ... the KDE (−9.5 and −10.9)"
    assert _r(hrun["mode_logp"]["backward"], 1) == -2.9
    assert _r(hrun["mode_logp"]["forward"], 1) == -10.4
    assert _r(hc["kde"]["mode_logp"]["backward"], 1) == -9.5
    assert _r(hc["kde"]["mode_logp"]["forward"], 1) == -10.9
    assert _r(hc["data_mode_shares"][1]) == 0.61
    # "against −3.4 for the states in transit between them"; "both above the −16.2 of the
    # states in transit"
    assert _r(run["transit_logp"], 1) == -3.4 and run["transit_logp"] < min(flow)
    assert _r(hrun["transit_logp"], 1) == -16.2
    assert hrun["transit_logp"] < min(hrun["mode_logp"].values())
    # "The flow favours the backward direction ... by 7.5 nats per state; the KDE by 1.4"
    assert _r(hrun["mode_logp"]["backward"] - hrun["mode_logp"]["forward"], 1) == 7.5
    assert _r(hc["kde"]["mode_logp"]["backward"] - hc["kde"]["mode_logp"]["forward"], 1) == 1.4


def test_the_samples_fall_to_the_modes_in_proportion_but_not_onto_them(fit):
    r4, run = fit["tasks"]["reacher4"], _run(fit, "reacher4")
    # "16/25/49/10% of samples against 19/28/48/5% of the states"
    assert [_r(x) for x in run["sample_mode_shares"]] == [0.16, 0.25, 0.49, 0.10]
    assert [_r(x) for x in r4["data_mode_shares"]] == [0.19, 0.28, 0.48, 0.05]
    # "within 2 cm of a target for 3% of the samples against 98% of the demonstration states"
    assert _r(sum(run["sample_at_mode_shares"])) == 0.03
    hc, hrun = fit["tasks"]["halfcheetah2"], _run(fit, "halfcheetah2")
    # "halfcheetah2: 27% running forward against 39%"
    assert (_r(hrun["sample_mode_shares"][0]), _r(hc["data_mode_shares"][0])) == (0.27, 0.39)
    assert hc["at_mode_tolerance"] == 1.5
    # "within 1.5 m/s of either running speed for 27% against 84%"
    assert (_r(sum(hrun["sample_at_mode_shares"])), _r(sum(hc["data_at_mode_shares"]))) == (
        0.27, 0.84)
    # "the data's forward velocity has two sharp peaks, at −6.0 and +8.6 m/s; the samples' is
    # one broad hump peaking near −4 m/s"
    g = np.array(hc["feature_grid"])
    data, samples = np.array(hc["feature_kde_data"]), np.array(hrun["feature_kde_samples"])
    neg = g < 0
    assert _r(g[neg][np.argmax(data[neg])], 1) == -6.0
    assert _r(g[~neg][np.argmax(data[~neg])], 1) == 8.6
    assert -5 < g[np.argmax(samples)] < -3
    assert samples.max() < 0.5 * data.max()


# -- the sigma_max sweep -------------------------------------------------------------------------

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


def test_reacher_sigma_max_sweep(fit):
    runs = {r["sigma_max"]: r for r in fit["tasks"]["reacher4"]["runs"] if r["seed"] == 0}
    assert sorted(runs) == [0.0, 0.03, 0.1, 0.3]
    pert = [runs[s]["heldout_nll"]["perturbed 0.05"] for s in sorted(runs)]
    # "falls from 2.2 (plain CNF) to −5.6, −8.2 and −12.0"
    assert [_r(x, 1) for x in pert] == [2.2, -5.6, -8.2, -12.0]
    clean = [runs[s]["heldout_nll"]["clean"] for s in sorted(runs)]
    # "all four are within about 1.1 nats of each other (−17.6 to −18.7), with no trend"
    assert _r(max(clean) - min(clean), 1) == 1.1
    assert (_r(max(clean), 1), _r(min(clean), 1)) == (-17.6, -18.7)
    assert clean != sorted(clean) and clean != sorted(clean, reverse=True)
    # "the log-density of the states in transit rises from −14.5 to −6.4, −3.4 and 1.4"
    assert [_r(runs[s]["transit_logp"], 1) for s in sorted(runs)] == [-14.5, -6.4, -3.4, 1.4]


def test_sigma_max_03_scored_best_off_the_data_and_close_on_it(fit):
    # "0.3 scored best off the data, and on it at most 0.2 nats behind the best SoftFlow (the
    # toy) or best of all (reacher4)"
    s = fit["toy"]["summary"]
    assert min(s, key=lambda k: s[k]["0.05"]["mean"]) == "0.3"
    best_soft_on = min(s[k]["0"]["mean"] for k in ("0.03", "0.1", "0.3"))
    assert 0 < s["0.3"]["0"]["mean"] - best_soft_on <= 0.2
    runs = {r["sigma_max"]: r["heldout_nll"] for r in fit["tasks"]["reacher4"]["runs"]}
    assert min(runs, key=lambda k: runs[k]["perturbed 0.05"]) == 0.3
    assert min(runs, key=lambda k: runs[k]["clean"]) == 0.3
