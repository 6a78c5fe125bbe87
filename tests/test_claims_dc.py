"""Chapter 04's stored coin-flip benchmark: the protocol it describes and the rules that judge
it (the chapter renders its numbers from the files, so no rounded copy is pinned here).

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


def test_chapter04_verdicts_from_the_three_seed_files_decide_nothing():
    """The whole-grid files have 3 seeds (2 in the learning-rate sweeps): below
    claims.MIN_SEEDS, so every task's verdict is inconclusive, whatever its interval."""
    for v in claims.verdicts(*claims.observations()):
        assert {p[1] for p in v.per_task} <= {"inconclusive"}, v.claim
        assert all(p[5] < claims.MIN_SEEDS for p in v.per_task)
