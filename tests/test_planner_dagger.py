"""DAgger from the planner (issue 39): its labels are the planner's own actions, an
interrupted run resumes to the same student, and another configuration's labels are refused."""

import dataclasses

import numpy as np
import pytest
import torch

from dc_lesson.data import rollout
from dc_lesson.experts import planner, planner_dagger as pd

TINY = pd.DaggerConfig(rounds=2, episodes=1, episode_steps=3, epochs=2, batch_size=2,
                       eval_episodes=1)


def test_round_zero_labels_are_the_planners_own_actions(tmp_path):
    pd.train("humanoid", TINY, hours=0, directory=tmp_path, progress=None)
    xs, ys, log = pd._load("humanoid", TINY, tmp_path)
    assert len(xs) == 1 and log[0]["rolled_out_by"] == "planner"
    alone, _ = planner.load_planner_expert("humanoid")
    ep = rollout.collect("humanoid", alone, 1, seed=pd.ROLLOUT_SEED, batch=1, max_steps=3,
                         progress=False)[0]
    np.testing.assert_array_equal(ys[0], ep.actions)       # the action it takes there
    np.testing.assert_array_equal(xs[0], ep.observations[:-1])


def test_a_resumed_run_ends_as_an_uninterrupted_one_and_other_labels_are_refused(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    whole = pd.train("humanoid", TINY, directory=a, progress=None)
    first = pd.train("humanoid", TINY, hours=0, directory=b, progress=None)
    assert not first["done"] and len(first["log"]) == 1
    rest = pd.train("humanoid", TINY, directory=b, progress=None)
    assert rest["done"] and len(rest["log"]) == 2
    assert [r["return"] for r in rest["log"]] == [r["return"] for r in whole["log"]]
    sa = torch.load(pd.paths("humanoid", a)["policy"], weights_only=True)
    sb = torch.load(pd.paths("humanoid", b)["policy"], weights_only=True)
    for k, v in sa["state_dict"].items():
        assert torch.equal(v, sb["state_dict"][k]), k
    with pytest.raises(ValueError, match="another DAgger configuration"):
        pd.train("humanoid", dataclasses.replace(TINY, epochs=3), directory=b, progress=None)


def test_the_record_reads_a_finished_run_and_an_unfinished_one(tmp_path, monkeypatch):
    monkeypatch.setitem(pd.RECIPES, "humanoid", TINY)
    assert pd.record("humanoid", tmp_path) is None
    pd.train("humanoid", TINY, hours=0, directory=tmp_path, progress=None)
    part = pd.record("humanoid", tmp_path)
    assert not part["done"] and part["student_return"] is None and len(part["rounds"]) == 1
    pd.train("humanoid", TINY, directory=tmp_path, progress=None)
    whole = pd.record("humanoid", tmp_path)
    assert whole["done"] and whole["student_return"]["n_episodes"] == TINY.eval_episodes
    assert [r["beta"] for r in whole["rounds"]] == [1.0, TINY.beta]
    assert [r["rolled_out_by"] for r in whole["rounds"]] == ["planner", "mixture"]
    assert whole["label_variance"] > 0


def test_the_planner_acts_with_probability_beta_and_labels_every_state():
    class Fake:   # a planner whose action is 1 everywhere
        def __call__(self, obs):
            return np.ones((len(obs), 2))
    obs = np.zeros((4000, 3), np.float32)
    for beta, share in ((0.0, 0.0), (1.0, 1.0)):
        lab = pd.Labeller(Fake(), lambda o: np.zeros((len(o), 2)), beta)
        assert lab(obs).mean() == share
    lab = pd.Labeller(Fake(), lambda o: np.zeros((len(o), 2)), 0.25,
                      np.random.default_rng(1))
    acted = lab(obs)[:, 0]
    assert abs(acted.mean() - 0.25) < 0.03 and set(acted) == {0.0, 1.0}
    assert np.all(lab.labels[0] == 1) and len(lab.obs[0]) == 4000   # every state labelled
    with pytest.raises(ValueError, match="probability"):
        pd.DaggerConfig(beta=1.5)
