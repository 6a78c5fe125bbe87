"""The start_noise study (issue 38's diagnosis of the hopper dips): its grid, its perturbation
and its rules on constructed records."""

import pytest
import torch

from dc_lesson import budget
from dc_lesson.experiments import studies
from dc_lesson.experiments.studies import competence, start_noise
from dc_lesson.nn.policies import GaussianPolicy


@pytest.mark.parametrize("name", ["smoke", "lesson"])
def test_the_grid_is_the_competence_keep_starts(name):
    b = budget.get(name)
    grid = studies.get("start_noise").grid(b)
    assert len(grid) == len(competence.KEEP_TASKS) * b.competence_keep_seeds
    keep = [c for c in studies.get("competence").grid(b) if c.variant == "keep"]
    # the very starts of the keep cells: same task, demonstrations, seed and BC epochs
    assert {(c.task, c.seed, c.n_demos) for c in grid} == {(c.task, c.seed, c.n_demos)
                                                          for c in keep}
    assert {c.config["start_epochs"] for c in grid} == {c.config["start_epochs"] for c in keep}
    assert {c.config["eval_seed"] for c in grid} == {c.config["eval_seed"] for c in keep}


def test_a_perturbation_moves_only_the_mean_network_by_its_scale_and_repeats():
    policy = GaussianPolicy(5, 2, hidden=(64, 64))
    a = start_noise.perturbed(policy, 1e-2, torch.Generator().manual_seed(1))
    b = start_noise.perturbed(policy, 1e-2, torch.Generator().manual_seed(1))
    moved = torch.cat([(p - q).reshape(-1) for p, q in zip(a.mean_net.parameters(),
                                                          policy.mean_net.parameters())])
    assert 0.009 < float(moved.detach().std()) < 0.011   # N(0, scale^2) on every weight
    assert all(torch.equal(p, q) for p, q in zip(a.parameters(), b.parameters()))
    assert torch.equal(a.log_std, policy.log_std)         # the mean action does not read it
    assert not any(p is q for p, q in zip(a.parameters(), policy.parameters()))


def test_a_start_topples_at_the_first_scale_where_a_draw_falls_past_the_dip():
    dip = competence.MAX_DIP
    scores = {"0.0001": [1.0, 1.0], "0.001": [1.0, 1.0 - dip], "0.003": [0.5, 1.0]}
    assert start_noise.topples(1.0, scores) == 0.003      # exactly the dip does not fall
    assert start_noise.topples(1.0, {"0.01": [0.95]}) is None
    recs = [{"cell": {"task": "hopper", "seed": s}, "result": {"start": 1.0, "noise": {
        "0.001": [1.0, 0.1, 1.0], "0.01": [0.1, 0.1, 0.1]}}} for s in range(2)]
    out = start_noise.aggregate(recs, budget.get("lesson"))
    shares = {(r["task"], r["scale"]): r for r in out["shares"]}
    assert (shares[("hopper", 0.001)]["fell"], shares[("hopper", 0.001)]["of"]) == (2, 6)
    assert shares[("hopper", 0.01)]["share"] == 1.0
    assert [s["topples at"] for s in out["seeds"]] == [0.001, 0.001]
