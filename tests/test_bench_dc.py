"""`dc-lesson bench dc` at the smoke budget: the record, the features file, the claims code."""

import json

import numpy as np
import pytest

from dc_lesson.experiments import dc as bench_dc, claims
from dc_lesson import budget
from dc_lesson.algorithms import dc
from dc_lesson.storage import read_result


@pytest.fixture(scope="module")
def smoke_record(tmp_path_factory):
    out = tmp_path_factory.mktemp("dc") / "dc_modes.json"
    record = bench_dc.run(["reacher2"], budget.get("smoke"), out=out, command="test")
    return out, record


def test_bench_dc_writes_a_record_the_chapter_can_read(smoke_record):
    out, record = smoke_record
    stored = read_result(out)
    assert stored["benchmark"] == "dc_modes" and stored["command"] == "test"
    smoke = budget.get("smoke")
    config = bench_dc.dc_config(smoke, seed=0)
    (run,) = stored["runs"]
    assert run["task"] == "reacher2" and run["seed"] == 0
    assert run["dc"]["env_steps"] == config.env_steps("reacher2")
    assert len(run["curve"]["param_change_l1"]) == config.loops * config.iterations
    assert set(run["bc"]) >= {"scaled_return", "emd", "kl", "rkl", "mode_shares"}
    from dc_lesson import tasks
    assert list(run["dc"]["mode_shares"]) == [*tasks.spec("reacher2").modes, "none"]
    assert [s["method"] for s in stored["summary"]] == ["bc", "dc"]
    assert all(s["scaled_return_std"] == 0.0 for s in stored["summary"])   # one seed

    features = bench_dc.load_features(out)
    assert set(features) == {"reacher2__expert", "reacher2__BC__seed0", "reacher2__DC__seed0"}
    assert all(f.dtype == np.float32 and f.shape[1] == 2 for f in features.values())
    with np.load(out.with_suffix(".npz"), allow_pickle=False) as f:
        assert len(f.files) == 3


def test_dc_config_spends_the_budgets_interactions():
    for name in ("smoke", "lesson", "paper"):
        b = budget.get(name)
        c = bench_dc.dc_config(b)
        spent = c.loops * c.iterations * c.batch_size
        assert b.il_steps - c.loops * c.batch_size < spent <= b.il_steps, name
    assert bench_dc.dc_config(budget.get("lesson"), loops=4).iterations * 4 * \
        dc.DCConfig().batch_size <= budget.get("lesson").il_steps


def test_claims_judge_a_record_without_gail_on_what_it_has(smoke_record):
    _, record = smoke_record
    rows = claims.table_one(record, {"summary": []})
    assert [r["method"] for r in rows] == ["BC", "DC"]
    obs = claims.legacy_observations(json.loads(json.dumps(record)))
    v = {x.claim: x for x in claims.verdicts(obs, {})}
    lowest = v[claims.LOWEST_DIVERGENCE.name]
    assert [p[1] for p in lowest.per_task] == ["inconclusive"]   # one seed: no interval
    assert v[claims.HIGHER_RETURN.name].per_task == ()           # no GAIL to compare with
    conv = v[claims.CONVERGES.name]
    assert conv.per_task and conv.per_task[0][1] in claims.VERDICTS
