"""Chapter 04's statements about stored results, checked against the result files.

Files: data/results/dc_modes.json (+ .npz), dc_ablation.json, dc_lr.json, written by
``dc-lesson bench dc | dc-ablation | dc-lr``, and GAIL's gail_modes.json, gail_lr.json.
"""

import numpy as np
import pytest

from dc_lesson.experiments import dc as bench_dc, claims
from dc_lesson.storage import read_result


@pytest.fixture(scope="module")
def dc_modes():
    return read_result("dc_modes.json")


@pytest.fixture(scope="module")
def gail_modes():
    return read_result("gail_modes.json")


def test_the_dc_benchmark_is_the_lesson_protocol_the_chapter_describes(dc_modes, gail_modes):
    assert dc_modes["budget"] == "lesson" and dc_modes["seeds"] == [0, 1, 2]
    assert dc_modes["tasks"] == ["reacher4", "reacher2", "halfcheetah2"]
    p = dc_modes["protocol"]
    assert p["demos"] == 18 and p["env_steps"] == 300_000 and p["eval_episodes"] == 50
    # GAIL ran the same protocol, so the two files can share one table.
    assert gail_modes["budget"] == "lesson" and gail_modes["seeds"] == dc_modes["seeds"]
    assert gail_modes["n_demos"] == p["demos"] and gail_modes["steps"] == p["env_steps"]
    assert gail_modes["eval_episodes"] == p["eval_episodes"]
    for r in dc_modes["runs"]:
        assert r["config"]["loops"] == 2 and r["config"]["update"] == "average"
        assert abs(r["dc"]["env_steps"] - p["env_steps"]) <= 0.05 * p["env_steps"]


def test_bc_rows_are_the_same_warm_start_in_both_files(dc_modes, gail_modes):
    """BC is DC's and GAIL's common start: trained with the same seeds and settings, it must
    measure identically in both benchmarks (one thread, deterministic)."""
    gail = {(r["task"], r["seed"]): r["BC"] for r in gail_modes["runs"]}
    for r in dc_modes["runs"]:
        g = gail[(r["task"], r["seed"])]
        for k in ("scaled_return", "emd", "kl", "rkl"):
            assert r["bc"][k] == pytest.approx(g[k], rel=1e-9, abs=1e-12), (r["task"], k)


def test_features_file_has_every_run(dc_modes):
    f = bench_dc.load_features("dc_modes.json")
    for r in dc_modes["runs"]:
        for m in ("BC", "DC"):
            assert f[f"{r['task']}__{m}__seed{r['seed']}"].shape[0] == 2000
    for t in dc_modes["tasks"]:
        assert f"{t}__expert" in f


def _rows():
    return {(r["task"], r["method"]): r for r in claims.table_one()}


def test_chapter04_table_prose_holds():
    r = _rows()
    for task in ("reacher4", "halfcheetah2"):
        for m in ("emd", "kl", "rkl"):
            assert r[task, "DC"][f"{m}_mean"] < min(r[task, "BC"][f"{m}_mean"],
                                                   r[task, "GAIL"][f"{m}_mean"]), (task, m)
    assert round(r["reacher4", "DC"]["emd_mean"], 3) == 0.080
    e = {k: r["reacher2", k]["emd_mean"] for k in ("BC", "GAIL", "DC")}
    assert e["BC"] < e["DC"] < e["GAIL"] and round(e["DC"], 3) == 0.144
    for task in ("reacher2", "halfcheetah2"):
        assert r[task, "DC"]["scaled_return_mean"] > max(r[task, "BC"]["scaled_return_mean"],
                                                         r[task, "GAIL"]["scaled_return_mean"])
    assert r["reacher4", "DC"]["scaled_return_mean"] < r["reacher4", "BC"]["scaled_return_mean"]
    assert round(r["halfcheetah2", "DC"]["scaled_return_mean"], 2) == 0.75
    assert round(r["reacher2", "DC"]["mode_shares_mean"]["red"], 2) == 0.92
    assert round(r["halfcheetah2", "DC"]["mode_shares_mean"]["backward"], 2) == 0.93
    assert round(r["reacher4", "DC"]["mode_shares_mean"]["yellow"], 2) == 0.01


def test_chapter04_reacher4_seed1_lost_return(dc_modes):
    s1 = next(x for x in dc_modes["runs"] if x["task"] == "reacher4" and x["seed"] == 1)
    assert round(s1["bc"]["scaled_return"], 2) == 0.61 and round(s1["dc"]["scaled_return"], 2) == 0.18
    gains = [x["dc"]["scaled_return"] > x["bc"]["scaled_return"]
             for x in dc_modes["runs"] if x["task"] == "reacher4"]
    assert sum(gains) == 2


def test_chapter04_ablation_prose_holds(dc_modes):
    ab = read_result("dc_ablation.json")
    ret = [round(x["dc"]["scaled_return"], 2) for x in ab["loops"]]
    assert ret == [0.17, 0.57, 0.30, 0.67, 0.28]
    assert ab["loops"][4]["dc"]["train_seconds"] < ab["loops"][3]["dc"]["train_seconds"]
    avg = [x["dc"] for x in dc_modes["runs"] if x["task"] == "reacher4"]
    admm = ab["admm_summary"]
    assert admm["scaled_return_mean"] < np.mean([x["scaled_return"] for x in avg])
    assert admm["emd_mean"] > np.mean([x["emd"] for x in avg])
    assert round(admm["scaled_return_mean"], 2) == 0.23


def test_chapter04_verdicts_from_the_three_seed_files_decide_nothing():
    """The whole-grid files have 3 seeds (2 in the learning-rate sweeps): below
    claims.MIN_SEEDS, so every task's verdict is inconclusive, whatever its interval."""
    for v in claims.verdicts():
        assert {p[1] for p in v.per_task} <= {"inconclusive"}, v.claim
        assert all(p[5] < claims.MIN_SEEDS for p in v.per_task)
    gail_lr = {s["lr"]: s["scaled_return_mean"] for s in read_result("gail_lr.json")["summary"]}
    assert gail_lr[3e-4] < gail_lr[1e-4] - 0.3        # GAIL already falls at 3e-4
