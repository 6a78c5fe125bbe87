"""Claims chapter 02 (book/02_gail.py) makes about stored results, checked against the files
data/results/gail_modes.json (+ .npz); the learning-rate sweep is a cell study now
(tests/test_ablations.py checks its rules)."""

import numpy as np
import pytest

from dc_lesson.experiments import gail as bench_gail
from dc_lesson.storage import read_result


@pytest.fixture(scope="module")
def modes():
    return read_result("gail_modes.json")


@pytest.fixture(scope="module")
def summary(modes):
    return {(r["task"], r["method"]): r for r in modes["summary"]}


def _runs(modes, task):
    return sorted((r for r in modes["runs"] if r["task"] == task), key=lambda r: r["seed"])


def _shares(modes, task, method, mode):
    return [r[method]["mode_shares"][mode] for r in _runs(modes, task)]


def test_the_benchmark_is_the_lesson_run_the_chapter_describes(modes):
    assert modes["budget"] == "lesson" and modes["seeds"] == [0, 1, 2]
    assert modes["tasks"] == ["reacher4", "reacher2", "halfcheetah2"]
    assert modes["steps"] == 300_000 and modes["n_demos"] == 18
    assert modes["eval_episodes"] == 50 and modes["eval_seed"] == 1000
    assert len(modes["runs"]) == 9
    assert all(r["steps"] == 73 * 4096 == 299_008 for r in modes["runs"])
    assert round(modes["wall_seconds"] / 60) == 22          # "22 minutes"
    cfg = modes["gail_config"]
    assert cfg["reward_form"] == "gail" and cfg["grad_penalty"] == 0 and cfg["value_warmup"] == 2
    assert cfg["disc_hidden"] == [64, 64] and cfg["disc_steps"] == 8 and cfg["disc_batch"] == 512
    assert (cfg["ppo"]["n_envs"], cfg["ppo"]["n_steps"], cfg["ppo"]["n_epochs"],
            cfg["ppo"]["n_minibatches"], cfg["ppo"]["lr"]) == (8, 512, 5, 8, 3e-4)
    assert cfg["ppo"]["ent_coef"] == 0 and cfg["ppo"]["anneal_lr"]
    info = modes["task_info"]
    assert info["reacher2"]["demo_mode_shares"] == {"red": 0.48, "blue": 0.52}
    assert info["reacher4"]["demo_mode_shares"]["green"] == 0.28
    assert info["halfcheetah2"]["demo_mode_shares"] == {"forward": 0.4, "backward": 0.6}


def test_reacher2_gail_collapses_onto_red_in_every_seed(modes):
    assert _shares(modes, "reacher2", "BC", "red") == [0.18, 0.36, 0.94]
    assert _shares(modes, "reacher2", "GAIL", "red") == [1.0, 0.84, 1.0]


def test_reacher4_two_of_three_seeds_collapse_onto_one_target(modes):
    runs = _runs(modes, "reacher4")
    assert runs[1]["GAIL"]["mode_shares"]["red"] == 0.86
    assert runs[2]["GAIL"]["mode_shares"]["yellow"] == 0.94
    assert runs[2]["BC"]["mode_shares"] == {"red": 0.3, "green": 0.16, "blue": 0.54,
                                            "yellow": 0.0}
    s0 = runs[0]["GAIL"]["mode_shares"]
    assert (s0["red"], s0["blue"], s0["yellow"]) == (0.26, 0.52, 0.2)
    assert round(runs[0]["BC"]["scaled_return"], 2) == 0.49
    assert round(runs[0]["GAIL"]["scaled_return"], 2) == -0.04
    assert max(_shares(modes, "reacher4", "GAIL", "green")) == 0.06       # "at most 0.06"


def _arrivals(task, method, seed=None):
    f = bench_gail.load_features("gail_modes.json")
    k = {"reacher4": 4, "reacher2": 2}[task]
    return bench_gail.on_target(f[bench_gail.feature_key(task, method, seed)], k)


def test_reacher2_arrivals_bc_leans_red_and_gail_arrives_at_red_or_nowhere():
    e = _arrivals("reacher2", "expert")
    assert round(e["share"], 2) == 0.98
    assert [round(e["split"][c], 2) for c in ("red", "blue")] == [0.48, 0.52]
    bc = [_arrivals("reacher2", "BC", s) for s in (0, 1, 2)]
    assert [round(a["share"], 2) for a in bc] == [0.30, 0.44, 0.77]
    assert [round(a["split"]["red"], 2) for a in bc] == [0.59, 0.72, 0.96]
    g = [_arrivals("reacher2", "GAIL", s) for s in (0, 1, 2)]
    assert abs(g[1]["share"] - 0.74) < 0.005 and g[1]["split"]["red"] == 1.0
    assert round(g[0]["share"], 2) == 0.02 and g[2]["share"] < 0.01


def test_reacher4_arrivals_gail_arrives_at_one_target_or_hardly_anywhere():
    bc = [_arrivals("reacher4", "BC", s) for s in (0, 1, 2)]
    assert [round(a["split"]["red"], 2) for a in bc] == [0.68, 0.97, 0.84]
    g = [_arrivals("reacher4", "GAIL", s) for s in (0, 1, 2)]
    assert round(g[1]["share"], 2) == 0.70 and round(g[1]["split"]["red"], 2) == 0.99
    assert round(g[2]["share"], 2) == 0.30 and round(g[2]["split"]["yellow"], 2) == 0.93
    assert g[0]["share"] < 0.04


def test_three_gail_reacher_policies_arrive_at_one_target_three_almost_nowhere():
    g = [_arrivals(t, "GAIL", s) for t in ("reacher4", "reacher2") for s in (0, 1, 2)]
    arriving = [a for a in g if a["share"] >= 0.25]
    assert len(arriving) == 3 and all(max(a["split"].values()) >= 0.9 for a in arriving)
    assert all(a["share"] < 0.04 for a in g if a["share"] < 0.25)


def test_five_of_six_gail_reacher_policies_favour_one_target_against_one_of_six_bc(modes):
    def lopsided(method):
        return sum(max(r[method]["mode_shares"].values()) >= 0.84
                   for t in ("reacher4", "reacher2") for r in _runs(modes, t))
    assert lopsided("GAIL") == 5 and lopsided("BC") == 1


def test_gail_coverage_is_worse_than_bc_on_the_reachers(summary):
    r = lambda t, m, k: round(summary[t, m][f"{k}_mean"], 3)  # noqa: E731
    assert (r("reacher4", "GAIL", "emd"), r("reacher4", "BC", "emd")) == (0.159, 0.116)
    assert (r("reacher2", "GAIL", "emd"), r("reacher2", "BC", "emd")) == (0.162, 0.092)
    assert (round(summary["halfcheetah2", "GAIL"]["emd_mean"], 2),
            round(summary["halfcheetah2", "BC"]["emd_mean"], 2)) == (4.11, 4.18)
    for task in ("reacher4", "reacher2", "halfcheetah2"):
        for k in ("kl", "rkl"):
            assert summary[task, "GAIL"][f"{k}_mean"] > summary[task, "BC"][f"{k}_mean"]


def test_halfcheetah2_neither_covers_both_modes_and_gail_runs_between_them(modes, summary):
    assert round(summary["halfcheetah2", "BC"]["mode_shares_mean"]["backward"], 2) == 0.92
    assert round(summary["halfcheetah2", "GAIL"]["mode_shares_mean"]["backward"], 2) == 0.82
    assert all(s > 0.5 for s in _shares(modes, "halfcheetah2", "GAIL", "backward"))
    f = bench_gail.load_features("gail_modes.json")
    expert = f[bench_gail.feature_key("halfcheetah2", "expert")][:, 0]
    assert -6.5 < np.median(expert[expert < -2]) < -5.5                 # "about -6"
    assert 8.0 < np.median(expert[expert > 2]) < 9.0                    # "about +8.5 m/s"
    medians = [np.median(f[bench_gail.feature_key("halfcheetah2", "GAIL", s)][:, 0])
               for s in (0, 1, 2)]
    assert [round(float(m), 1) for m in medians] == [-1.8, -0.8, -0.1]


def test_gail_returns_fall_below_bc_and_spread_over_seeds(modes, summary):
    worse = sum(r["GAIL"]["scaled_return"] < r["BC"]["scaled_return"] for r in modes["runs"])
    assert worse == 5
    means = {t: (round(summary[t, "GAIL"]["scaled_return_mean"], 2),
                 round(summary[t, "BC"]["scaled_return_mean"], 2))
             for t in ("reacher4", "reacher2", "halfcheetah2")}
    assert means == {"reacher4": (0.30, 0.45), "reacher2": (0.23, 0.50),
                     "halfcheetah2": (0.31, 0.57)}
    stds = [round(summary[t, m]["scaled_return_std"], 2) for t in ("reacher4", "reacher2")
            for m in ("GAIL", "BC")]
    assert stds == [0.36, 0.19, 0.44, 0.24]
    reach = [r["GAIL"]["scaled_return"] for t in ("reacher4", "reacher2") for r in _runs(modes, t)]
    assert (round(min(reach), 2), round(max(reach), 2)) == (-0.04, 0.75)


def test_learning_curves_jump_between_batches(modes):
    jumps = []
    for r in modes["runs"]:
        y = np.array(r["curve"]["episode_return"])
        assert len(y) > 30 and np.all(np.isfinite(y))
        jumps.append(np.abs(np.diff(y)))
    mean_jumps = [j.mean() for j in jumps]
    assert round(min(mean_jumps)) == 16 and round(max(mean_jumps)) == 64
    assert round(max(j.max() for j in jumps)) == 430
    # halfcheetah2's training return climbs from 113 to 211 (first and last three points).
    y = np.array([r["curve"]["episode_return"] for r in _runs(modes, "halfcheetah2")]).mean(0)
    assert (round(y[:3].mean()), round(y[-3:].mean())) == (113, 211)
    for task in ("reacher4", "reacher2"):                 # "ends about where it began"
        y = np.array([r["curve"]["episode_return"] for r in _runs(modes, task)]).mean(0)
        assert abs(y[-3:].mean() - y[:3].mean()) < 20
    # The evaluation's mean action ends below the BC start on average on every task.
    for task in modes["tasks"]:
        runs = _runs(modes, task)
        assert np.mean([r["GAIL"]["return"] for r in runs]) < np.mean([r["BC"]["return"]
                                                                       for r in runs])


def test_the_discriminator_wins_at_the_end(modes):
    acc_e = [r["disc_final"]["acc_expert"] for r in modes["runs"]]
    acc_l = [r["disc_final"]["acc_learner"] for r in modes["runs"]]
    assert round(min(acc_e), 2) == 0.93 and round(max(acc_e), 2) == 0.99
    assert round(min(acc_l), 2) == 0.69 and round(max(acc_l), 2) == 0.88


def test_features_file_holds_every_run_subsampled(modes):
    f = bench_gail.load_features("gail_modes.json")
    for t in modes["tasks"]:
        assert bench_gail.feature_key(t, "expert") in f
        for m in bench_gail.METHODS:
            for s in modes["seeds"]:
                x = f[bench_gail.feature_key(t, m, s)]
                assert x.dtype == np.float32 and 0 < len(x) <= bench_gail.FEATURES_PER_RUN


# -- the benchmark rerun at lr 1e-4 (data/results/gail_modes_lr1e-4.json) -----------------------

@pytest.fixture(scope="module")
def slow():
    return read_result("gail_modes_lr1e-4.json")


def _slow_arrivals(task, seed):
    f = bench_gail.load_features("gail_modes_lr1e-4.json")
    k = {"reacher4": 4, "reacher2": 2}[task]
    return bench_gail.on_target(f[bench_gail.feature_key(task, "GAIL", seed)], k)


def test_the_rerun_is_the_benchmark_with_one_learning_rate_of_1e_4(modes, slow):
    assert slow["budget"] == "lesson" and slow["seeds"] == [0, 1, 2]
    assert slow["tasks"] == modes["tasks"] and slow["steps"] == modes["steps"]
    cfg = slow["gail_config"]
    assert cfg["ppo"]["lr"] == cfg["disc_lr"] == 1e-4
    same = {k: v for k, v in cfg.items() if k not in ("ppo", "disc_lr")}
    assert same == {k: v for k, v in modes["gail_config"].items()
                    if k not in ("ppo", "disc_lr")}
    assert round(slow["wall_seconds"] / 60) == 19                      # "19 minutes"
    # The BC starts are the same policies (same seeds, same demonstrations).
    for a, b in zip(modes["runs"], slow["runs"]):
        assert a["BC"]["scaled_return"] == b["BC"]["scaled_return"]


def test_at_1e_4_reacher4_policies_stop_arriving(slow):
    shares = [_slow_arrivals("reacher4", s)["share"] for s in (0, 1, 2)]
    assert [round(x, 2) for x in shares] == [0.02, 0.02, 0.05]
    s = {(r["task"], r["method"]): r for r in slow["summary"]}
    assert (round(s["reacher4", "GAIL"]["scaled_return_mean"], 2),
            round(s["reacher4", "GAIL"]["scaled_return_std"], 2)) == (-0.04, 0.02)
    runs = _runs(slow, "reacher4")
    assert runs[1]["GAIL"]["mode_shares"]["blue"] == 0.8
    assert runs[2]["GAIL"]["mode_shares"]["green"] == 0.82


def test_at_1e_4_one_reacher2_seed_arrives_only_at_red(slow):
    a = [_slow_arrivals("reacher2", s) for s in (0, 1, 2)]
    assert round(a[2]["share"], 2) == 0.79 and a[2]["split"]["red"] > 0.99
    assert round(_runs(slow, "reacher2")[2]["GAIL"]["scaled_return"], 2) == 0.81
    assert a[0]["share"] < 0.08 and a[1]["share"] < 0.08
    runs = _runs(slow, "reacher2")
    assert runs[0]["GAIL"]["mode_shares"]["red"] == 1.0
    assert runs[1]["GAIL"]["mode_shares"]["blue"] == 1.0


def test_at_1e_4_halfcheetah2_policies_stand_still(slow):
    f = bench_gail.load_features("gail_modes_lr1e-4.json")
    for seed in (0, 1, 2):
        v = f[bench_gail.feature_key("halfcheetah2", "GAIL", seed)][:, 0]
        assert abs(float(np.median(v))) < 0.05
    s = {(r["task"], r["method"]): r for r in slow["summary"]}
    assert (round(s["halfcheetah2", "GAIL"]["scaled_return_mean"], 2),
            round(s["halfcheetah2", "GAIL"]["scaled_return_std"], 2)) == (0.08, 0.01)
    for r in _runs(slow, "halfcheetah2"):
        assert 0.4 <= r["GAIL"]["mode_shares"]["forward"] <= 0.6      # "near one half"


def test_at_1e_4_the_emd_stays_above_bcs(slow):
    s = {(r["task"], r["method"]): r for r in slow["summary"]}
    got = [round(s[t, "GAIL"]["emd_mean"], 3) for t in ("reacher4", "reacher2")]
    assert got == [0.125, 0.160] and round(s["halfcheetah2", "GAIL"]["emd_mean"], 2) == 5.56
    for t in ("reacher4", "reacher2", "halfcheetah2"):
        assert s[t, "GAIL"]["emd_mean"] > s[t, "BC"]["emd_mean"]
