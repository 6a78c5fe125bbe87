"""``dc-lesson perf flow-fit``: at smoke it fits every variant on every seed, scores each by
both solvers, and the summary's rule picks the fastest variant within the tolerance."""

import json

import pytest

from dc_lesson import budget, cli
from dc_lesson.perf import flow_fit


def test_the_benchmark_runs_every_variant_and_stores_its_record(tmp_path, monkeypatch):
    monkeypatch.setenv(budget.ENV_VAR, "smoke")
    out = tmp_path / "ff.json"
    assert cli.main(["perf", "flow-fit", "--out", str(out)]) == 0
    rec = json.loads(out.read_text())
    assert rec["command"].startswith("dc-lesson") and rec["budget"] == "smoke"
    assert {r["variant"] for r in rec["rows"]} == set(flow_fit.VARIANTS)
    assert len(rec["rows"]) == 2 * len(flow_fit.VARIANTS)
    by = {(r["variant"], r["seed"]): r for r in rec["rows"]}
    today = next(iter(flow_fit.VARIANTS))
    assert by[("rk4, step 0.5", 0)]["step_size"] == 0.5
    assert by[("euler, step 0.25", 0)]["solver"] == "euler"
    assert by[(today, 0)]["step_size"] == 0.25 and by[(flow_fit.DEFAULTS, 0)]["step_size"] == 0.5
    assert by[("rk4, step 0.25, half the iterations", 0)]["iterations"] == \
        max(1, by[(today, 0)]["iterations"] // 2)
    for r in rec["rows"]:
        assert r["fit_seconds"] > 0 and abs(r["nll_own_solver"] - r["nll_reference"]) < 0.5
    # the reward's solver: every setting on every seed, scored against the reference
    ev = rec["reward_solver"]
    assert sorted((e["seed"], e["eval_step_size"], e["nodes"], e["tanh"]) for e in ev) == \
        sorted((s, *x) for s in (0, 1) for x in flow_fit.EVAL_SETTINGS)
    table = flow_fit.reward_table(rec)
    assert [(m["eval_step_size"], m["nodes"], m["tanh"]) for m in table] == \
        list(flow_fit.EVAL_SETTINGS)
    assert [m["default"] for m in table].count(True) == 1
    assert all(0 <= e["mean_abs_error"] <= e["max_abs_error"] and e["rank_correlation"] <= 1
               for e in ev)
    assert cli.main(["perf", "flow-fit", "--tasks", "reacher4", "reacher2"]) == 2


def test_the_reward_accuracy_is_scored_against_the_reference_solver():
    import torch
    from dc_lesson.density import softflow
    torch.manual_seed(0)
    x = torch.randn(300, 2) * torch.tensor([1.0, 0.2])
    flow, _ = softflow.fit(x, softflow.SoftFlowConfig(hidden=(16, 16), iterations=30),
                           progress=False)
    rows = {r["eval_step_size"]: r for r in flow_fit.eval_accuracy(
        flow, x[:100], settings=((0.25, 4, "torch"), (1.0, 4, "numpy")))}
    assert set(rows) == {0.25, 1.0} and all(r["seconds"] > 0 for r in rows.values())
    assert 0 < rows[0.25]["mean_abs_error"] < 0.01 and rows[0.25]["rank_correlation"] > 0.99
    # a solver that is wrong by a constant keeps the order but not the values
    real = flow.log_prob
    flow.log_prob = lambda s, **kw: real(s, **kw) + (0.5 if kw.get("step_size") else 0.0)
    off = flow_fit.eval_accuracy(flow, x[:100], settings=((0.25, 4, "torch"),))[0]
    assert off["mean_abs_error"] == pytest.approx(0.5, abs=0.01)
    assert off["rank_correlation"] == pytest.approx(rows[0.25]["rank_correlation"])
    assert flow.net.tanh_kernel == "torch"          # the flow's own kernel is put back


def _row(variant, seed, seconds, nll):
    return {"variant": variant, "seed": seed, "fit_seconds": seconds, "nll_reference": nll}


def test_the_cheapest_variant_within_the_tolerance_is_chosen_on_every_seed():
    names = list(flow_fit.VARIANTS)
    rows = [_row(names[0], s, 10.0, -5.0) for s in (0, 1)]
    rows += [_row(names[1], 0, 5.0, -5.05), _row(names[1], 1, 5.0, -4.95)]   # within 0.1
    rows += [_row(names[2], 0, 2.0, -5.2), _row(names[2], 1, 2.0, -4.5)]     # one seed worse
    s = {x["variant"]: x for x in flow_fit.summarise(rows)}
    assert s[names[1]]["speedup"] == pytest.approx(2.0)
    assert s[names[1]]["nll_change"] == pytest.approx([-0.05, 0.05])
    assert s[names[2]]["worst_nll_change"] == pytest.approx(0.5)
    assert flow_fit.cheapest_within(list(s.values())) == names[1]
    assert flow_fit.cheapest_within(list(s.values()), tolerance=1.0) == names[2]
