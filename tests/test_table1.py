"""The table1 study (chapter 04's Table I): its rows, their configs, the mixture start, the
observations its aggregate pairs, the control rule, and one real cell at smoke."""

import copy
import json

import numpy as np
import pytest
import torch

from dc_lesson import budget
from dc_lesson.algorithms import bc
from dc_lesson.experiments import aggregate, cells, table_one
from dc_lesson.experiments.studies import table1
from dc_lesson.nn.mixture import MixturePolicy

# the rules on constructed records; the stored competence gate's reach: test_competence.py
pytestmark = pytest.mark.usefixtures("judge_every_learner")

LESSON = budget.get("lesson")


def test_every_row_is_listed_for_every_task_and_seed_with_the_core_first():
    grid = table1.cells_at(LESSON)
    learners = [c for c in grid if c.learner != "expert"]
    for row in table1.ROWS:
        for task in ("reacher4", "reacher2", "halfcheetah2"):
            seeds = sorted(c.seed for c in learners if c.row == row and c.task == task)
            want = LESSON.seeds_for(task)
            if table1.ROWS[row].mixture or table1.ROWS[row].mixture_seeds:
                # beyond the paper, and costly (or their control): the first five
                want = want[:LESSON.table1_mixture_seeds]
                assert len(want) == 5
            assert seeds == list(want), (row, task)
    stages = [c.stage for c in learners]
    assert stages == sorted(stages), "a sweep runs stage by stage: the list is in stage order"
    first = [c for c in learners if c.stage == 1]
    assert {c.row for c in first} == {"bc-all", "bc-full", "bc-lib", "gail", "dc"}
    # seed-major inside a stage: every row of seed 0 comes before any row of seed 1
    assert max(i for i, c in enumerate(first) if c.seed == 0) < \
        min(i for i, c in enumerate(first) if c.seed == 1)
    assert len({c.name for c in grid if c.task == "reacher4"}) == \
        len([c for c in grid if c.task == "reacher4"]), "cell names are unique"


def test_each_control_changes_exactly_what_its_name_says():
    cfg = {r: json.loads(table1.learner_config(table1.ROWS[r], LESSON, 0).to_json())
           for r in table1.ROWS}
    base_dc = cfg["dc"]
    for row, field, value in (("dc-noppo", "ppo_step", False), ("dc-raw", "reward", "raw"),
                              ("dc-gailreward", "reward", "gail")):
        diff = {k for k in base_dc if base_dc[k] != cfg[row][k]}
        assert diff == {field} and cfg[row][field] == value, row
    assert {k for k in cfg["gail"] if cfg["gail"][k] != cfg["gail-state"][k]} == \
        {"disc_actions"}
    assert {k for k in cfg["gail"] if cfg["gail"][k] != cfg["gail-noisy"][k]} == \
        {"start_log_std"} and cfg["gail-noisy"]["start_log_std"] == -0.5
    assert cfg["bc-all"]["stop_on_others"] and cfg["bc-all"]["val_fraction"] == 0
    # bc-full: the same data, no early stopping, smaller minibatches; nothing else differs
    assert {k for k in cfg["bc-all"] if cfg["bc-all"][k] != cfg["bc-full"][k]} == \
        {"stop_on_others", "batch_size"}
    assert not cfg["bc-full"]["stop_on_others"] and cfg["bc-full"]["val_fraction"] == 0
    assert {k for k in cfg["bc-full"] if cfg["bc-full"][k] != cfg["bc-mix"][k]} == {"policy"}
    # bc-lib: imitation 1.0.1's recipe, 50,000 minibatches of 32 on 18,000 pairs
    lib = cfg["bc-lib"]
    assert (lib["hidden"], lib["norm_obs"], lib["batch_size"], lib["log_std_init"]) == \
        ([32, 32], False, 32, 0.0)
    assert abs(lib["epochs"] * -(-18_000 // 32) - 50_000) < 18_000 // 32
    assert not lib["stop_on_others"] and lib["val_fraction"] == 0
    assert cfg["bc-mix"]["policy"] == "mixture" and cfg["bc-all"]["policy"] == "gaussian"
    # bc-full-coin: the Gaussian twin of bc-mix-coin, trained alike on the same demonstrations
    assert {k for k in cfg["bc-full-coin"] if cfg["bc-full-coin"][k] != cfg["bc-mix-coin"][k]} \
        == {"policy"} and cfg["bc-full-coin"]["policy"] == "gaussian"
    coin = {r: next(x for x in table1.cells_at(LESSON) if x.row == r and x.task == "reacher2"
                    and x.seed == 0) for r in ("bc-full-coin", "bc-mix-coin")}
    assert coin["bc-full-coin"].config["demos"] == coin["bc-mix-coin"].config["demos"]
    # the coin rows read other demonstrations, so their cells' configs (and hashes) differ
    c = {r: next(x for x in table1.cells_at(LESSON) if x.row == r and x.task == "reacher4"
                 and x.seed == 0) for r in ("dc", "dc-coin")}
    assert c["dc"].config["demos"]["sha256"] != c["dc-coin"].config["demos"]["sha256"]
    assert c["dc-coin"].config["demo_variant"] == "coin"


def test_the_mixture_start_keeps_means_and_weights_and_resets_every_spread():
    torch.manual_seed(0)
    pol = MixturePolicy(6, 2, n_components=3, hidden=(16, 16))
    with torch.no_grad():   # a trained-looking head: state-dependent, small spreads
        pol.head.weight.normal_(0, 0.5)
        pol.head.bias.normal_(-3, 0.5)
    start = table1._mixture_start(pol)
    obs = torch.randn(64, 6)
    w0, m0, s0 = pol.components(obs)
    w1, m1, s1 = start.components(obs)
    assert torch.equal(w0, w1) and torch.equal(m0, m1)
    assert torch.allclose(s1, torch.full_like(s1, bc.WARM_START_LOG_STD))
    assert not torch.allclose(s0, s1)
    assert torch.equal(pol.components(obs)[2], s0), "the original is not changed"


def _record(row, task, seed, start=None, final=None):
    learner, _, variant = row.partition("-")
    res = {"final": {"mean": final, "sampled": final}}
    if start is not None:
        res["start"] = {"mean": start, "sampled": start}
    return {"cell": {"learner": learner, "variant": variant, "task": task, "n_demos": 18,
                     "seed": seed}, "config": {"dc": {"iterations": 5}}, "result": res}


def test_observations_name_each_start_and_keep_it_once():
    m = lambda v: {"emd": v, "scaled_return": 1 - v, "mode_shares": None}
    recs = [_record("dc", "reacher4", 0, m(0.3), m(0.2)),
            _record("gail", "reacher4", 0, m(0.3), m(0.4)),
            _record("dc-coin", "reacher4", 0, m(0.5), m(0.6)),
            _record("dc-mix", "reacher4", 0, m(0.7), m(0.1)),
            _record("bc-all", "reacher4", 0, None, m(0.25))]
    obs = table1.observations(recs, "mean")
    rows = sorted(o["row"] for o in obs)
    assert rows == sorted(["bc", "dc", "gail", "bc-coin", "dc-coin", "bc-mixstart", "dc-mix",
                           "bc-all"])
    assert next(o for o in obs if o["row"] == "dc")["iterations"] == 5


def _paired(delta, n_seeds, noise=0.01):
    rng = np.random.default_rng(1)
    obs = []
    for s in range(n_seeds):
        base = rng.normal(0.5, 0.2)
        obs += [{"row": "dc", "task": "t", "n_demos": 18, "seed": s,
                 "emd": base + delta + rng.normal(0, noise)},
                {"row": "dc-noppo", "task": "t", "n_demos": 18, "seed": s, "emd": base}]
    (p,) = aggregate.paired(obs, "dc", "dc-noppo", measures=("emd",))
    return p


@pytest.mark.parametrize("delta, n, want", [(0.1, 10, "contradicted"), (-0.1, 10, "reproduced"),
                                            (0.0, 10, "equal within 0.05"),
                                            (-0.1, 3, "not judged: fewer than 5 paired seeds")])
def test_the_control_rule_gives_each_of_its_words(delta, n, want):
    # a control asks "is a better?": lower EMD is better
    assert table_one.word(_paired(delta, n), "emd") == want
    assert table_one.word(None, "emd") == "not judged: not run yet"


def test_a_partial_aggregate_says_how_much_of_the_grid_it_rests_on(tmp_path, monkeypatch):
    """Aggregating a grid with cells missing: refused without --partial (naming the command),
    written with it, saying n of N and complete False."""
    study = cells.Study("toy_partial", "toy", cells=lambda b: [
        cells.make_cell("toy_partial", "dc", "toy", 1, s, {"x": 1}) for s in range(4)],
        run_cell=None, aggregate=lambda recs, b: {"seeds_seen": [r["cell"]["seed"]
                                                                for r in recs]})
    for c in study.cells(budget.get("smoke"))[:3]:
        cells.write_record(c, {"v": c.seed}, None, cells.provenance(
            command="test", budget="smoke", threads=1, wall_seconds=1.0), root=tmp_path)
    from dc_lesson.experiments import studies
    monkeypatch.setattr(studies, "get", lambda name: study)
    with pytest.raises(aggregate.AggregateError, match="1 of the 4 cells"):
        aggregate.write("toy_partial", budget.get("smoke"), root=tmp_path, results=tmp_path)
    path = aggregate.write("toy_partial", budget.get("smoke"), root=tmp_path,
                           results=tmp_path, partial=True)
    rec = json.loads(path.read_text())
    assert rec["complete"] is False and rec["cells"]["n"] == 3 and rec["cells"]["of"] == 4
    assert rec["seeds_seen"] == [0, 1, 2]


def test_one_mixture_dc_cell_runs_at_smoke_and_repeats(tmp_path, monkeypatch):
    """The costliest path of the study (mixture BC, its reset start, DC from it, four
    evaluations) runs end to end, and the same cell gives the same numbers twice."""
    from dc_lesson.experiments import protocol
    smoke = budget.get("smoke")
    cell = next(c for c in table1.cells_at(smoke) if c.row == "dc-mix" and c.task == "reacher2"
                and c.seed == 0)
    ref = protocol.reference_cell("reacher2")
    if not ref.path().exists():
        pytest.skip("the reacher2 reference cell is not stored")
    needs = [(cells.read_record(ref.path()), cells.read_features(ref.path()))]
    a, fa = table1.run_cell(cell, needs)
    b, fb = table1.run_cell(cell, needs)
    assert cells.split_timing(a)[0] == cells.split_timing(b)[0]   # wall times aside
    assert np.array_equal(fa["final"], fb["final"])
    assert set(a["final"]) == {"mean", "sampled"} and set(a["start"]) == {"mean", "sampled"}
    assert set(a["final"]["mean"]["mode_shares"]) == {"red", "blue", "none"}


def test_only_the_rows_that_own_a_start_evaluate_it():
    """The controls and baselines share the core rows' Gaussian start on the realizable
    demonstrations: they skip its evaluation; the mixture and coin rows evaluate their own."""
    for c in table1.cells_at(LESSON):
        if c.learner in ("expert", "bc"):
            continue
        row = table1.ROWS[c.row]
        owns = row.stage == 1 or row.mixture or bool(row.demos)
        assert c.config.get("evaluate_start", True) is owns, c.row


def test_the_single_mode_grid_has_every_learner_task_count_and_seed():
    """table3 (Table III / Figures 9, 11): the full grid, curves only at the fewest
    demonstrations and only for RL learners, interactions per task from the budget."""
    from dc_lesson.experiments.studies import table3
    b = budget.get("lesson")
    grid = [c for c in table3.cells_at(b) if c.learner != "expert"]
    planners = {"walker", "ant", "humanoid"}   # the sampling-planner experts
    rl = len(table3.LEARNERS) - 1
    full = len(b.bc_demo_counts) * b.table3_seeds
    # BC on every row of every task; the RL learners on the planner tasks on one row only
    assert len(grid) == (len(table3.TASKS) * full
                         + (len(table3.TASKS) - len(planners)) * full * rl
                         + len(planners) * rl)
    for c in grid:
        if c.task in planners and c.learner != "bc":
            assert (c.seed, c.n_demos) == (0, min(b.bc_demo_counts))
    assert {r["task"] for r in table3.reduced_rows(b)} == planners
    for c in grid:
        cfg = c.config
        assert cfg["curve"] == (c.n_demos == min(b.bc_demo_counts) and c.learner != "bc")
        assert cfg["steps"] == (0 if c.learner == "bc" else b.table3_steps_for(c.task))
    experts = [c for c in table3.cells_at(b) if c.learner == "expert"]
    assert sorted({c.task for c in experts}) == sorted(set(table3.TASKS) - planners)
    for c in grid:   # a planner task reads no reference and computes no divergence
        assert c.config["divergences"] == (c.task not in planners)
        assert (c.needs == ()) == (c.task in planners)
    assert {m["task"] for m in table3.expert_manifest() if not m["expert_row"]} == planners


def test_a_planner_task_cell_measures_returns_without_a_reference():
    """A table3 cell on walker (a planner expert) runs with no needs: its scaled return is
    measured, its divergences are None (not computed against the training demonstrations)."""
    from dc_lesson.experiments.studies import table3
    smoke = budget.get("smoke")
    cell = next(c for c in table3.cells_at(smoke) if c.learner == "bc" and c.task == "walker")
    out, _ = table3.run_cell(cell, [])
    assert out["final"]["emd"] is None and out["final"]["kl"] is None
    assert np.isfinite(out["final"]["scaled_return"])


def test_a_cached_start_is_the_policy_a_fresh_warm_start_gives():
    """table1 keeps each seed's BC start per worker: the cached copy must equal a start
    trained afresh, parameter for parameter, and cells get copies, not the cached object."""
    from dc_lesson.data import store
    smoke = budget.get("smoke")
    demos = store.load_demos("reacher2", n_trajectories=4)
    c = {"bc_max_epochs": 3}
    table1._im._STARTS.clear()
    first = table1._start("reacher2", demos, None, 1, smoke, c, False)
    second = table1._start("reacher2", demos, None, 1, smoke, c, False)
    fresh = bc.warm_start_policy(demos, 1, max_epochs=3)
    for p, q, r in zip(first.parameters(), second.parameters(), fresh.parameters()):
        assert torch.equal(p, q) and torch.equal(p, r)
    assert first is not second
    with torch.no_grad():
        next(first.parameters()).add_(1.0)    # a cell training its copy leaves the cache alone
    again = table1._start("reacher2", demos, None, 1, smoke, c, False)
    assert torch.equal(next(again.parameters()), next(fresh.parameters()))


def test_the_summary_words_come_from_the_rule_on_the_aggregate(monkeypatch):
    """A constructed grid where DC lowers the EMD of its start on every seed gives
    'reproduced'; the same grid with DC equal to its start gives 'equal within' the bound."""
    def recs(delta):
        rng = np.random.default_rng(0)
        out = []
        for s in range(10):
            base = 0.3 + rng.normal(0, 0.05)
            m = lambda e: {"emd": e, "kl": e, "rkl": e, "scaled_return": 1 - e, "return": 1,
                           "return_std": 0, "mode_shares": {"red": 0.5, "blue": 0.5,
                                                            "none": 0.0}}
            out.append(_record("dc", "reacher2", s, m(base),
                               m(base + delta + rng.normal(0, 0.002))))
        for r in out:
            r["config"]["eval_episodes"] = 50
        return out
    monkeypatch.setattr(table1._im, "reference_shares", lambda r: {"reacher2": {
        "red": 0.5, "blue": 0.5, "none": 0.0}})
    for delta, want in ((-0.1, "*reproduced*"), (0.0, "*equal within")):
        agg = table1.aggregate(recs(delta), LESSON)
        (line,) = table_one.summary_lines(agg)
        assert "`reacher2` (10 paired seeds)" in line and want in line.split(";")[0]


def test_the_headline_table_names_its_seed_and_puts_the_expert_floor_first():
    from dc_lesson.experiments import headline
    r = {"emd": 0.1, "kl": 1.0, "rkl": 2.0, "scaled_return": 0.5, "train_seconds": 1.0,
         "mode_shares": {"red": 0.5, "none": 0.5}}
    text = headline.format_table("reacher4", budget.get("smoke"), {"expert": r, "BC": r}, seed=7)
    lines = text.splitlines()
    assert "seed 7" in lines[0] and lines[2].startswith("expert") and lines[3].startswith("BC")
    assert "lower is better" in lines[-1] and "'none'" in lines[-1]


def test_the_ordering_beside_the_paper_reads_orders_not_values():
    """Our means in the paper's EMD order (on another scale) give tau 1 and the same lowest
    row; the reverse order gives tau -1 and disagrees; fewer than three shared rows, no tau."""
    paper = {k: v[0] for k, v in table_one.PAPER_TABLE_I["reacher4"].items()}
    order = sorted(paper, key=paper.get)

    def rec(values):
        return {"mean": {"table": [{"task": "reacher4", "row": k, "emd_mean": v}
                                   for k, v in values.items()]}}
    same = table_one.rank_agreement(rec({k: 10 + i for i, k in enumerate(order)}), "reacher4")
    assert same["tau"] == pytest.approx(1.0) and same["agree"] and same["our_order"] == order
    back = table_one.rank_agreement(rec({k: -i for i, k in enumerate(order)}), "reacher4")
    assert back["tau"] == pytest.approx(-1.0) and not back["agree"]
    assert back["our_order"] == order[::-1] and back["paper_order"] == order
    two = table_one.rank_agreement(rec({order[0]: 1.0, order[1]: 2.0}), "reacher4")
    assert two["tau"] is None and two["agree"]


def test_costs_keep_one_machine_and_take_the_median_per_100k(tmp_path, monkeypatch):
    """Cells written before ``since`` are left out; the training cost is the median of
    train_seconds / steps * 1e5 (one slow cell does not move it); a BC row has none."""
    monkeypatch.setenv("DC_LESSON_DATA", str(tmp_path))
    grid = [cells.make_cell("table1", "gail", "reacher4", 18, s, {"steps": 200_000})
            for s in range(4)] + [cells.make_cell("table1", "bc", "reacher4", 18, 0, {"x": 1})]
    seconds = {0: 10.0, 1: 12.0, 2: 500.0, 3: 99.0}
    times = {0: "2026-12-02T06:00", 1: "2026-12-02T06:10", 2: "2026-12-02T06:20",
             3: "2026-12-01T06:00"}
    for c in grid:
        prov = cells.provenance(command="test", budget="lesson", threads=1, wall_seconds=60.0)
        prov["time"] = times[c.seed] if c.learner == "gail" else "2026-12-02T07:00"
        train = {"train_seconds": seconds[c.seed]} if c.learner == "gail" else {}
        cells.write_record(c, {"v": 1, **train}, None, prov)
    from dc_lesson.experiments import studies

    class Toy:
        def grid(self, b):
            return grid
    monkeypatch.setattr(studies, "get", lambda name: Toy())
    out = {r["row"]: r for r in table_one.costs({"budget": "lesson"}, since="2026-12-02T05:00")}
    assert out["gail"]["cells"] == 3 and out["gail"]["train_per_100k"] == pytest.approx(6.0)
    assert out["bc"]["train_per_100k"] is None and out["bc"]["minutes"] == pytest.approx(1.0)
    every = {r["row"]: r for r in table_one.costs({"budget": "lesson"})}
    assert every["gail"]["cells"] == 4
    early = {r["row"]: r for r in table_one.costs({"budget": "lesson"}, "2026-12-02T05:00",
                                                  "2026-12-02T06:15")}
    assert early["gail"]["cells"] == 2 and "bc" not in early


def test_coverage_figures_draw_each_task_with_rows_and_read_bc_from_dc_starts(monkeypatch):
    """A task with fewer than two rows that ran is skipped; "BC" is the DC cells' start."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    asked = []

    def features(rec, task, row, which="final"):
        asked.append((task, row, which))
        if task == "reacher2":
            return None
        return np.zeros((20, 2)) + 0.1 if task.startswith("reacher") else np.linspace(
            -5, 5, 20)[:, None]
    monkeypatch.setattr(table_one, "features", features)
    figs = list(table_one.coverage_figures({}, {"expert": "expert", "bc": "BC"}, "t"))
    assert len(figs) == 2 and ("reacher4", "dc", "start") in asked
    assert figs[0]._suptitle.get_text() == "reacher4: t"
    plt.close("all")


def test_a_table3_cell_gives_the_same_numbers_with_its_start_cached_or_fresh():
    """table3's RL cells share the seed's warm start through the worker's cache: a cell run
    on a cold cache and again on a warm one (the second trains no BC) gives the same numbers."""
    from dc_lesson.experiments import protocol
    from dc_lesson.experiments.studies import table3
    smoke = budget.get("smoke")
    cell = next(c for c in table3.cells_at(smoke) if c.learner == "pwil"
                and c.task == "reacher1" and c.n_demos == max(smoke.bc_demo_counts))
    ref = protocol.reference_cell("reacher1")
    if not ref.path().exists():
        pytest.skip("the reacher1 reference cell is not stored")
    needs = [(cells.read_record(ref.path()), cells.read_features(ref.path()))]
    table1._im._STARTS.clear()
    cold, _ = table3.run_cell(cell, needs)
    assert len(table1._im._STARTS) == 1
    warm, _ = table3.run_cell(cell, needs)
    assert cells.split_timing(cold)[0] == cells.split_timing(warm)[0]


def test_against_start_counts_collapses_and_falls_per_seed_and_words_the_pair(monkeypatch):
    """A constructed coin grid: GAIL sends every episode of seeds 0-6 to red (its start
    splits red/blue) and ends below its start in those seeds; the line counts 7 collapsed
    seeds against the start's 0, 7 of 10 below the start, and words the paired EMD by the
    rule ('inconclusive': its 0.035 rise is under the smallest effect)."""
    def recs():
        rng = np.random.default_rng(0)
        out = []
        for s in range(10):
            collapsed = s < 7
            start = {"emd": 0.1, "kl": 1, "rkl": 1, "scaled_return": 0.6, "return": 1,
                     "return_std": 0, "mode_shares": {"red": 0.5, "blue": 0.4, "none": 0.1}}
            final = {**start, "emd": 0.1 + (0.05 if collapsed else 0) + rng.normal(0, 0.002),
                     "scaled_return": 0.4 if collapsed else 0.7,
                     "mode_shares": ({"red": 0.9, "blue": 0.0, "none": 0.1} if collapsed
                                     else {"red": 0.5, "blue": 0.4, "none": 0.1})}
            r = _record("gail-coin", "reacher2", s, start, final)
            r["config"]["eval_episodes"] = 50
            out.append(r)
        return out
    monkeypatch.setattr(table1._im, "reference_shares", lambda r: {"reacher2": {
        "red": 0.5, "blue": 0.5, "none": 0.0}})
    agg = table1.aggregate(recs(), LESSON)
    (line,) = table_one.against_start(agg, "gail-coin", "bc-coin")
    assert "(10 seeds)" in line
    assert "collapsed seeds gail-coin 7, its start 0" in line
    assert "below its own start in 7 of 10 seeds" in line
    assert "EMD gail-coin - bc-coin" in line and "*inconclusive*" in line.split("EMD")[1]   # below the smallest effect
    assert "from 0.40 to 0.70" in line
    assert table_one.against_start(agg, "dc-coin", "bc-coin") == []   # a row not run: no line


def _mix_rec(diffs_by_measure, n_seeds=5):
    """A table1 aggregate with one paired entry ``bc-mix - bc-full`` on reacher4."""
    from dc_lesson.evaluation import stats
    entry = {"task": "reacher4", "n_demos": 18, "a": "bc-mix", "b": "bc-full",
             "n_seeds": n_seeds, "seeds": list(range(n_seeds))}
    rng = np.random.default_rng(0)
    for m, d in diffs_by_measure.items():
        x = rng.normal(0.5, 0.1, n_seeds)
        y = x + d + rng.normal(0, 0.005, n_seeds)
        entry[m] = stats.paired_diff(list(y), list(x)).to_dict()
        entry[f"{m}_diffs"] = (y - x).tolist()
    return {a: {"paired": [entry], "table": [], "expert": []} for a in ("mean", "sampled")}


def test_the_mixture_words_turn_by_each_measures_direction():
    from dc_lesson.experiments import table_one_mixture as tm
    rec = _mix_rec({"mode_tv": -0.2, "scaled_return": -0.2, "emd": 0.0})
    t = tm.tally(rec)[("bc-mix", "bc-full")]
    assert t["mode_tv"]["reproduced"] == ["reacher4"]          # lower TV is better
    assert t["scaled_return"]["contradicted"] == ["reacher4"]  # lower return is worse
    assert t["emd"]["equal within 0.05"] == ["reacher4"]
    assert t["mode_tv"]["not judged: not run yet"] == ["reacher2", "halfcheetah2"]
    few = tm.tally(_mix_rec({"mode_tv": -0.2}, n_seeds=3))[("bc-mix", "bc-full")]
    assert few["mode_tv"] == {"not judged: fewer than 5 paired seeds": ["reacher4"],
                              "not judged: not run yet": ["reacher2", "halfcheetah2"]}
    line = tm.lines(rec)[0]
    assert "mode TV: reproduced on 1 (reacher4)" in line
    assert "scaled return: contradicted on 1" in line


def test_mixture_shares_follow_the_experts_order_with_none_last():
    from dc_lesson.experiments import table_one_mixture as tm
    part = {"expert": [{"task": "reacher2", "row": "expert",
                        "mode_shares_mean": {"red": 0.5, "blue": 0.5, "none": 0.0}}],
            "table": [{"task": "reacher2", "row": "bc-mix",
                       "mode_shares_mean": {"none": 0.2, "blue": 0.8}}]}
    rec = {"mean": part}
    assert list(tm.shares(rec, "reacher2", "bc-mix")) == ["red", "blue", "none"]
    assert tm.shares(rec, "reacher2", "bc-mix") == {"red": 0.0, "blue": 0.8, "none": 0.2}
    assert tm.shares(rec, "reacher2", "dc-mix") == {}


def test_the_aggregate_pairs_the_mode_tv_per_seed(monkeypatch):
    shares = {"reacher2": {"red": 0.5, "blue": 0.5, "none": 0.0}}
    monkeypatch.setattr(table1._im, "reference_shares", lambda records: shares)
    m = lambda tv_red: {"emd": 0.1, "kl": 0.1, "rkl": 0.1, "scaled_return": 0.5, "return": 1.0,
                        "mode_shares": {"red": 0.5 + tv_red, "blue": 0.5 - tv_red,
                                        "none": 0.0}}
    recs = []
    for s in range(5):
        recs.append(_record("bc-mix", "reacher2", s, None, m(0.1)))
        recs.append(_record("bc-full", "reacher2", s, None, m(0.3 + 0.01 * s)))
    for r in recs:
        r["config"]["eval_episodes"] = 50
    out = table1.aggregate(recs, LESSON)
    e = table_one.paired(out, "bc-mix", "bc-full", "reacher2")
    assert e["mode_tv_diffs"] == pytest.approx([-0.2 - 0.01 * s for s in range(5)])
    assert table_one.word(e, "mode_tv") == "reproduced"      # lower mode TV: better


def _modes_rec(tv, diff, n_seeds=10):
    """A table1 aggregate for the mode answer: ``tv[(task, row)]`` a row's mean mode TV (its
    per-seed values spread evenly over +-0.03 about it), ``diff[(row, task)]`` the paired
    mode-TV difference ``dc - row``."""
    from dc_lesson.evaluation import stats
    rng = np.random.default_rng(1)
    modes = [{"task": t, "row": r, "tv": (v + np.linspace(-0.03, 0.03, n_seeds)).tolist(),
              "tv_ci": {"mean": v, "lo": v - 0.03, "hi": v + 0.03}} for (t, r), v in tv.items()]
    pairs = []
    for (row, task), d in diff.items():
        x = rng.normal(0.5, 0.1, n_seeds)
        y = x + d + rng.normal(0, 0.005, n_seeds)
        pairs.append({"task": task, "a": "dc", "b": row, "n_seeds": n_seeds,
                      "mode_tv": stats.paired_diff(list(y), list(x)).to_dict(),
                      "mode_tv_diffs": (y - x).tolist()})
    return {a: {"paired": pairs, "modes": modes, "table": [], "expert": []}
            for a in ("mean", "sampled")}


def test_the_mode_answer_judges_dc_against_the_better_trained_bc_and_the_floor():
    from dc_lesson.experiments import table_one_modes as tm
    tasks = ("reacher2", "reacher4", "halfcheetah2")
    tv = {**{(t, "bc-full"): 0.40 for t in tasks}, **{(t, "bc-lib"): 0.20 for t in tasks},
          **{(t, "expert"): 0.10 for t in tasks}, **{(t, "dc"): 0.30 for t in tasks}}
    tv[("halfcheetah2", "bc-lib")] = 0.80          # the library's BC fails there: bc-full is
    tv[("halfcheetah2", "dc")] = 0.12              # the comparator, and DC sits at the floor
    diff = {**{("bc", t): -0.2 for t in tasks}, **{("bc-lib", t): +0.1 for t in tasks},
            **{("bc-full", t): -0.1 for t in tasks}}
    rec = _modes_rec(tv, diff)
    assert [tm.best_bc(rec, t) for t in tasks] == ["bc-lib", "bc-lib", "bc-full"]
    a = tm.against(rec)
    assert [a[tm.BEST_BC][t][:2] for t in tasks] == [
        ("bc-lib", "contradicted"), ("bc-lib", "contradicted"), ("bc-full", "reproduced")]
    assert all(a["bc"][t][1] == "reproduced" for t in tasks)      # lower TV is better
    assert a["gail"]["reacher2"][1] == "not judged: not run yet"
    # the floor is the same claim, unpaired (Welch): DC 0.2 above the expert's own on the
    # reachers is contradicted; 0.02 above it on halfcheetah2 is equal within 0.05
    fl = tm.floor(rec)
    assert fl["reacher2"][0] == "contradicted"
    assert fl["halfcheetah2"][0] == "equal within 0.05"
    c = tm.conclusion(rec)
    assert "is reproduced against the better-trained BC on 1 of 3 tasks (halfcheetah2) only" in c
    assert ("Against the expert scored like a learner (unpaired): contradicted on 2 "
            "(reacher2, reacher4); equal within 0.05 on 1 (halfcheetah2)") in c
    lines = tm.lines(rec)
    assert "reproduced on 1 (halfcheetah2); contradicted on 2 (reacher2, reacher4)" in lines[1]
    assert "reacher2 *contradicted* (DC 0.30 [" in lines[-1] and "unpaired, Welch" in lines[-1]
    for m in rec["mean"]["modes"]:            # no per-seed values: no word
        if (m["task"], m["row"]) == ("reacher2", "dc"):
            del m["tv"]
    assert tm.floor(rec)["reacher2"][0] == "not judged: no per-seed mode TVs"


def test_the_mode_answer_says_each_outcome_in_the_rules_words():
    """The head of the answer for each outcome of the rule, and every comparator's part is
    the count of the words :func:`against` and :func:`floor` gave: no word of its own."""
    from dc_lesson.experiments import table_one_modes as tm
    from dc_lesson.experiments.table_one_mixture import count_words
    tasks = ("reacher2", "reacher4", "halfcheetah2")
    tv = {**{(t, "bc-full"): 0.40 for t in tasks}, **{(t, "bc-lib"): 0.30 for t in tasks},
          **{(t, "expert"): 0.10 for t in tasks}, **{(t, "dc"): 0.11 for t in tasks}}

    def said(d_start, d_best, n_seeds=10):
        diff = {**{("bc", t): d_start for t in tasks}, **{("bc-lib", t): d_best for t in tasks}}
        rec = _modes_rec(tv, diff, n_seeds)
        c = tm.conclusion(rec)
        a, fl = tm.against(rec), tm.floor(rec)
        for label, per in (("its start", a["bc"]), ("the better-trained BC", a[tm.BEST_BC])):
            grouped: dict = {}
            for t, (_, w, _) in per.items():
                grouped.setdefault(w, []).append(t)
            assert f"Against {label}: {count_words(grouped)}" in c
        assert c.startswith("Under the mean action, *DC keeps more of the expert's modes*")
        return c, fl

    head = lambda c: c.split(". ")[0]
    c, fl = said(-0.2, -0.2)
    assert head(c).endswith("is reproduced against the better-trained BC on every task: DC "
                            "keeps the modes better than BC can")
    c, _ = said(-0.2, 0.0)
    assert head(c).endswith("is reproduced against its start on every task, and against the "
                            "better-trained BC on no task")
    assert "Against the better-trained BC: equal within 0.05 on every task" in c
    c, _ = said(-0.2, +0.2)
    assert head(c).endswith(", where it is contradicted on every task")
    c, _ = said(0.0, 0.0)
    assert head(c).endswith("is reproduced against its start on no task")
    assert "Against its start: equal within 0.05 on every task" in c
    c, _ = said(+0.2, +0.2)
    assert head(c).endswith("is contradicted against its start on every task")
    # four seeds are too few for a word: no claim either way, and the reason is said
    c, fl = said(-0.2, -0.2, n_seeds=4)
    assert head(c).endswith("is not judged against its start on any task")
    assert "Against its start: not judged: fewer than 5 paired seeds on every task" in c
    assert "(unpaired): not judged: fewer than 5 seeds on a side on every task" in c
    # DC 0.01 above the expert's own mode TV: equal within the smallest effect
    c, fl = said(-0.2, 0.0)
    assert {w for w, _, _ in fl.values()} == {"equal within 0.05"}
    assert "(unpaired): equal within 0.05 on every task" in c
    for old in ("higher", "lower on", "no more", "fewer", "distinguish"):
        assert old not in c, old


def test_the_mode_answer_flags_a_comparator_that_reaches_nothing():
    from dc_lesson.experiments import table_one_modes as tm
    tasks = ("reacher2", "reacher4", "halfcheetah2")
    tv = {**{(t, "bc-lib"): 0.2 for t in tasks}, **{(t, "dc"): 0.3 for t in tasks}}
    rec = _modes_rec(tv, {**{("bc", t): -0.3 for t in tasks},
                          **{("bc-lib", t): 0.1 for t in tasks}})
    rec["sampled"]["table"] = [{"task": "reacher4", "row": "bc",
                                "mode_shares_mean": {"red": 0.05, "none": 0.95}},
                               {"task": "reacher2", "row": "bc",
                                "mode_shares_mean": {"red": 0.6, "none": 0.4}}]
    line = tm.lines(rec, "sampled")[0]
    assert "a low bar where most of its episodes arrive nowhere (none: reacher4 0.95)" in line
    assert "low bar on reacher4," in tm.conclusion(rec, "sampled")
    assert "low bar" not in tm.conclusion(rec, "mean")     # the mean rows reach their modes


def test_the_mode_mechanism_says_what_the_ppo_step_and_the_density_add():
    from dc_lesson.experiments import table_one_modes as tm
    tasks = ("reacher2", "reacher4", "halfcheetah2")

    def said(d_noppo, d_gail, none=None):
        rec = _modes_rec({}, {**{("dc-noppo", t): d_noppo for t in tasks},
                              **{("dc-gailreward", t): d_gail for t in tasks}})
        if none is not None:
            rec["mean"]["table"] = [{"task": "reacher4", "row": "dc-noppo",
                                     "mode_shares_mean": {"red": 1 - none, "none": none}}]
        return tm.mechanism(rec)

    ppo = "keeps more modes than BC continuation* (DC's mode TV below `dc-noppo`'s): "
    density = "discriminator reward in its place* (below `dc-gailreward`'s): "
    s = said(-0.2, 0.0)
    assert ppo + "reproduced on every task" in s
    assert density + "equal within 0.05 on every task" in s
    assert "not the density in particular" in s
    assert density + "reproduced on every task" in said(-0.2, -0.2)
    assert density + "contradicted on every task" in said(-0.2, +0.2)
    assert ppo + "contradicted on every task" in said(+0.2, 0.0)
    s = said(0.0, 0.0)
    assert ppo + "equal within 0.05 on every task" in s and "in particular" not in s
    assert "a low bar on reacher4," in said(-0.2, 0.0, none=0.9)


def test_said_judges_any_measure_with_its_direction_floor_and_the_rules_interval():
    """``table_one.said`` on a constructed paired entry: the t interval the rule reads, the
    word for the given direction, the divergence bound from ``floor``, and the side named."""
    from dc_lesson.experiments import verdicts
    far = {"task": "t", "a": "n=4", "b": "n=25", "late_median_diffs": [0.5, 0.6, 0.4, 0.55, 0.45]}
    t = verdicts.paired_t(far["late_median_diffs"])
    text = table_one.said(far, "late_median", direction=+1, better="farther")
    assert text == (f"{verdicts.fmt_num(t.mean)} [{verdicts.fmt_num(t.lo)}, "
                    f"{verdicts.fmt_num(t.hi)}], *reproduced* (n=4 farther)")
    assert "*contradicted* (n=4 worse)" in table_one.said(far, "late_median", direction=-1)
    small = {"task": "t", "a": "a", "b": "b", "emd_diffs": [0.01, -0.01, 0.0, 0.005, -0.005]}
    assert table_one.word(small, "emd", floor=0.05) == "equal within 0.05"
    assert table_one.word(small, "emd", floor=0.001) == verdicts.INCONCLUSIVE
    assert table_one.said(None, "emd") == "*not judged: not run yet*"


def _headline_rec(dc_emd_factor, seeds={"reacher2": 10, "halfcheetah2": 5}):
    """A table1 aggregate for the headline across tasks: per task the expert's EMD floor
    (0.02 on the reacher, 2.0 on the cheetah: two scales), the expert at 1 floor, BC at 3
    floors and DC at ``dc_emd_factor`` floors per seed (+-0.1 floor), GAIL on the reacher
    only; scaled returns expert 1, BC 0.5, DC 0.7."""
    floor = {"reacher2": 0.02, "halfcheetah2": 2.0}
    obs = []
    for task, n in seeds.items():
        for s in range(n):
            jitter = 0.1 * (s - (n - 1) / 2) / n
            for row, f, ret in (("expert", 1.0, 1.0), ("bc", 3.0, 0.5),
                                ("dc", dc_emd_factor, 0.7), ("gail", 2.0, 0.9),
                                ("bc-lib", 0.1, 1.0)):
                if row == "gail" and task != "reacher2":
                    continue
                obs.append({"task": task, "row": row, "seed": s, "n_demos": 18,
                            "emd": floor[task] * (f + jitter), "scaled_return": ret + jitter})
    expert = [{"task": t, "row": "expert", "emd_mean": f} for t, f in floor.items()]
    return {a: {"observations": obs, "expert": expert} for a in ("mean", "sampled")}


def test_the_headline_across_tasks_is_iqm_in_expert_floors_and_p_of_improvement():
    rows = {r["row"]: r for r in table_one.across_tasks(_headline_rec(2.0))}
    # GAIL ran on one task only: the strata are the tasks every headline row ran on, so
    # with GAIL present the headline rests on reacher2 alone
    assert rows["bc"]["tasks"] == 1 and rows["bc"]["runs"] == 10
    rec = _headline_rec(2.0)
    for part in rec.values():
        part["observations"] = [o for o in part["observations"] if o["row"] != "gail"]
    rows = {r["row"]: r for r in table_one.across_tasks(rec)}
    assert list(rows) == ["expert", "bc", "dc"]          # bc-lib is no headline row
    assert rows["bc"]["tasks"] == 2 and rows["bc"]["runs"] == 15
    # EMD in expert floors: both tasks' expert rows are at 1 floor, whatever their scale
    assert rows["expert"]["EMD (in expert floors)"].startswith("1.00")
    assert rows["bc"]["EMD (in expert floors)"].startswith("3.00")
    assert rows["dc"]["EMD (in expert floors)"].startswith("2.00")
    # DC is lower than BC on every run of every task: P(dc lower EMD) is 1; its return is
    # higher than BC's: P 1 too, and never above the expert's
    assert rows["bc"]["P(dc lower EMD)"] == "1.00"
    assert rows["bc"]["P(dc higher return)"] == "1.00"
    assert rows["expert"]["P(dc lower EMD)"] == "0.00"
    assert rows["dc"]["P(dc lower EMD)"] == "" and rows["dc"]["P(dc higher return)"] == ""
    # DC at BC's level: half of the run pairs each way (ties count half)
    even = {r["row"]: r for r in table_one.across_tasks(
        {a: {**p, "observations": [o if o["row"] != "dc" else
                                   {**o, "emd": o["emd"] * 1.5} for o in p["observations"]]}
         for a, p in rec.items()})}
    assert even["bc"]["P(dc lower EMD)"].startswith("0.50")
    # a task without the expert's floor cannot be put in floors: it is left out of the
    # headline on both measures
    for part in rec.values():
        part["expert"] = part["expert"][:1]
    rows = {r["row"]: r for r in table_one.across_tasks(rec)}
    assert rows["bc"]["tasks"] == 1 and rows["bc"]["runs"] == 10
    # the shared estimator: lower is better with better=-1; the target's own row has no P
    from dc_lesson.experiments import report
    by = {"bc": {"a": [3.0, 3.0]}, "dc": {"a": [1.0, 1.0], "b": [1.0]}}
    (bc, dc) = report.across_tasks(by, ("bc", "dc"), better=-1)
    assert bc["strata"] == 1 and bc["P"] == "1.00" and dc["P"] == ""
    assert report.across_tasks(by, ("bc", "dc"))[0]["P"] == "0.00"
    assert report.across_tasks(by, ("bc",)) == []                 # the target did not run


def test_the_imitation_check_is_unpaired_and_in_the_rules_words():
    def ref(ours, theirs):
        return {"task": "reacher4", "n_demos": 18, "n_episodes": 50,
                "rows": [{"library": "ours", "seed": s, "scaled_return": v}
                         for s, v in enumerate(ours)] +
                        [{"library": "imitation", "seed": s, "scaled_return": v}
                         for s, v in enumerate(theirs)]}
    same = [0.90, 0.91, 0.92, 0.93, 0.94, 0.95]
    s = table_one.against_imitation(ref(same, same[::-1]))
    assert "*equal within 0.05*" in s and "unpaired" in s and "Welch" in s
    # the pairing is not used: ours shifted seed by seed against reversed seeds still equal
    low = [v - 0.3 for v in same]
    s = table_one.against_imitation(ref(low, same))
    assert "*contradicted* (ours worse)" in s and "ours minus imitation -0.300 [" in s
    assert "(lowest 0.600)" in s and "over 6 seeds (lowest 0.900)" in s
    assert "*reproduced* (ours better)" in table_one.against_imitation(ref(same, low))
    # a wide spread cannot tell: inconclusive, not a paired word
    wide = [0.3, 0.95, 0.4, 0.9, 0.5, 0.96]
    assert "*inconclusive*" in table_one.against_imitation(ref(wide, same))
    assert "*not judged: fewer than 5 seeds on a side*" in \
        table_one.against_imitation(ref(same[:4], same))


def test_the_mode_answer_is_held_back_while_dc_is_not_shown_competent():
    from dc_lesson.experiments import table_one_modes as modes
    gate = {"dc": "failed the competence gate — keep on hopper: a checkpoint fell"}
    rec = {"mean": {"observations": [], "paired": [], "expert": []}}
    for said in (modes.conclusion(rec, competence=gate), modes.mechanism(rec, competence=gate)):
        assert "not judged: dc failed the competence gate — keep on hopper" in said
        assert "reproduced" not in said and "contradicted" not in said


def test_arrival_separates_going_nowhere_from_covering_the_modes():
    # a row that mostly arrives nowhere but, when it arrives, always goes to one mode
    nowhere = [{"mode_shares": {"red": 0.2, "blue": 0.0, "none": 0.8}},
               {"mode_shares": {"red": 0.0, "blue": 0.3, "none": 0.7}}]
    got = table_one.arrival(nowhere)
    assert got["arrived"] == pytest.approx(0.25)
    assert got["largest_of_arrivals"] == pytest.approx(1.0)      # collapsed among arrivals
    even = [{"mode_shares": {"red": 0.5, "blue": 0.5, "none": 0.0}}]
    assert table_one.arrival(even) == {"arrived": 1.0, "largest_of_arrivals": 0.5,
                                       "collapsed_among_arrivals": 0, "seeds_arriving": 1}
    assert table_one.arrival(nowhere)["collapsed_among_arrivals"] == 2
    # a seed that arrives nowhere at all has no largest mode of arrivals
    lost = [{"mode_shares": {"red": 0.0, "blue": 0.0, "none": 1.0}}]
    assert table_one.arrival(lost) == {"arrived": 0.0, "largest_of_arrivals": None,
                                       "collapsed_among_arrivals": 0, "seeds_arriving": 0}
    assert table_one.arrival([{"scaled_return": 1.0}]) is None


def test_arrival_lines_say_each_rows_arrivals_and_collapsed_seeds_per_task():
    obs = [{"task": "reacher2", "row": "gail-coin", "seed": s,
            "mode_shares": {"red": 0.2, "blue": 0.0, "none": 0.8}} for s in range(3)]
    obs += [{"task": "reacher2", "row": "expert", "seed": s,
             "mode_shares": {"red": 0.5, "blue": 0.5, "none": 0.0}} for s in range(3)]
    lines = table_one.arrival_lines({"mean": {"observations": obs}}, ("expert", "gail-coin"))
    assert lines == ["* `reacher2`: `expert` arrives at a mode in 1.00 of its episodes, 0.50 "
                     "of those at its largest mode, 0 of the 3 seeds that arrive anywhere with "
                     "at least 80% of their arrivals at one mode; `gail-coin` arrives at a "
                     "mode in 0.20 of its episodes, 1.00 of those at its largest mode, 3 of "
                     "the 3 seeds that arrive anywhere with at least 80% of their arrivals at "
                     "one mode."]


def test_the_collapse_words_say_which_row_collapses_where_counting_episodes_going_nowhere():
    two = {"red": 0.5, "blue": 0.5, "none": 0.0}
    nowhere = {"red": 0.2, "blue": 0.0, "none": 0.8}
    obs = [{"task": "reacher2", "row": "gail-coin", "seed": s, "mode_shares": nowhere}
           for s in range(3)]
    obs += [{"task": "reacher2", "row": "dc-coin", "seed": s,
             "mode_shares": two if s else nowhere} for s in range(3)]
    obs += [{"task": "reacher4", "row": "dc-coin", "seed": 0, "mode_shares": nowhere}]
    words = table_one.collapse_words({"mean": {"observations": obs}},
                                     ("gail-coin", "dc-coin", "bc-coin"))
    assert words == ("`gail-coin` collapses on `reacher2` (3 of 3 seeds); `dc-coin` collapses "
                     "on `reacher4` (1 of 1 seeds); not on `reacher2` (1 of 3 seeds).")


def test_a_comparison_over_the_tasks_is_one_holm_family():
    # issue 40: chapter 5 worded each (baseline, task) alone; table_one.family adjusts a
    # comparison's tasks together, so a p of 0.048 on one task of three is not decisive
    diffs = {table_one.TASKS[0]: [0.10, 0.30, 0.02, 0.25, 0.08],
             table_one.TASKS[1]: [0.1, -0.1, 0.05, -0.05, 0.0],
             table_one.TASKS[2]: [0.1, -0.1, 0.05, -0.05, 0.0]}
    paired = [{"a": "dc", "b": "bc", "task": task, "n_seeds": 5, "scaled_return_diffs": d}
              for task, d in diffs.items()]
    rec = {"mean": {"paired": paired, "expert": []}}
    alone = table_one.word({"a": "dc", "b": "bc", "task": table_one.TASKS[0],
                            "scaled_return_diffs": diffs[table_one.TASKS[0]]},
                           "scaled_return", rec, competence={})
    got = table_one.family(rec, "dc", "bc", "scaled_return", competence={})
    assert alone == "reproduced" and got[table_one.TASKS[0]].word == "inconclusive"
    assert got[table_one.TASKS[0]].p_holm == pytest.approx(3 * 0.0481, abs=2e-3)


def test_a_grid_without_a_row_leaves_its_controls_and_comparators_out():
    """The rerun under the gate has no GAIL and none of DC's diagnostics: its controls,
    mode comparators and mixture comparisons leave them out instead of reading "not run
    yet" forever, while a row of the design that has not run yet still says so."""
    from dc_lesson.experiments import table_one_mixture as tx
    from dc_lesson.experiments import table_one_modes as tm
    tasks = ("reacher2", "reacher4", "halfcheetah2")
    tv = {**{(t, r): 0.3 for t in tasks for r in ("bc-full", "bc-lib", "expert", "dc")}}
    rec = _modes_rec(tv, {("bc", t): -0.2 for t in tasks})
    assert "gail" in tm.against(rec)                    # no design record: every row kept
    assert any(c["a - b"] == "gail - bc-lib" for c in table_one.controls(rec))
    rec["rows"] = {r: {} for r in ("bc-full", "bc-lib", "dc", "dc-lib", "dril", "bc-mix",
                                   "dc-mix")}
    a = tm.against(rec)
    assert "gail" not in a and "dc-noppo" not in a and a["dril"]["reacher2"][1] == \
        "not judged: not run yet"                      # in the design, not yet run
    got = {c["a - b"] for c in table_one.controls(rec)}
    assert "dc-lib - bc-lib" in got and "dc - bc-lib" in got
    assert not any("gail" in x or "noppo" in x for x in got)
    assert not any("gail" in line or "noppo" in line for line in tm.lines(rec))
    assert "not asked of this grid" in tm.mechanism(rec)
    # no bc-mixstart in the design: the mixture DC's loop is measured against bc-mix
    comps = {(a_, b_) for a_, b_, *_ in tx.comparisons(rec)}
    assert ("dc-mix", "bc-mix") in comps and ("dc-mix", "dc") in comps
    assert not any("coin" in a_ for a_, _ in comps)   # no coin rows in this design
    assert table_one.in_grid(rec, "bc-mix (unmatched)") and table_one.in_grid(rec, "bc-coin")


def test_float_rounding_prints_as_zero_and_a_small_difference_does_not():
    from dc_lesson.experiments import report, verdicts
    assert report.fmt(np.mean([0.1, 0.2, -0.3]), -1.0, 1.0) == "0.00 [-1.00, 1.00]"
    assert verdicts.fmt_num(-5.6e-17) == "+0.000"
    assert report.fmt(3e-4) == "3.0e-04" and verdicts.fmt_num(-3e-4) == "-3.0e-04"


def test_the_cell_readers_read_the_aggregates_own_study(monkeypatch):
    """The rerun's coverage figures once drew the first grid's cells: every reader of cells
    now asks the study the aggregate names (``benchmark``), and an old record without it
    reads ``table1``."""
    from dc_lesson.experiments import studies
    asked = []

    class _Study:
        def grid(self, b):
            return []

    def get(name):
        asked.append(name)
        return _Study()

    monkeypatch.setattr(studies, "get", get)
    assert table_one.features({"benchmark": "modes", "budget": "lesson"}, "reacher4", "dc") \
        is None
    table_one.final_logs({"benchmark": "modes", "budget": "lesson"}, "dc")
    table_one.features({"budget": "lesson"}, "reacher4", "dc")
    assert asked == ["modes", "modes", "table1"]
    assert table_one.study_of({"benchmark": "modes"}) == "modes"
