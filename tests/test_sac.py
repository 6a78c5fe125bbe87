"""The SAC expert trainer: its pieces against their definitions, resume bit for bit, and its
refusals. (Whether it learns is measured by the stored expert runs, not here: a SAC run that
learns a locomotion task costs hours on this machine.)"""

import dataclasses

import numpy as np
import pytest
import torch

from dc_lesson.experts import sac

EPS32 = float(np.finfo(np.float32).eps)


def test_twin_q_is_two_independent_mlps():
    torch.manual_seed(0)
    q = sac.TwinQ(5, (7, 3))
    obs, act = torch.randn(11, 3), torch.randn(11, 2)
    out = q(obs, act)
    assert out.shape == (2, 11)
    x = torch.cat([obs, act], -1)
    for k in range(2):   # member k by plain matrix products of its own weights
        h = x
        for i, (w, b) in enumerate(zip(q.weights, q.biases)):
            h = h @ w[k] + b[k]
            if i < len(q.weights) - 1:
                h = torch.relu(h)
        # float32 rounding of a sum of a few terms: tolerance from eps, not from one machine
        tol = 16 * EPS32 * (1 + h.abs().max().item())
        assert torch.allclose(out[k], h.squeeze(-1), atol=tol, rtol=0)
    assert not torch.allclose(out[0], out[1])   # the members are initialised apart


def test_squashed_log_prob_matches_the_change_of_variables():
    torch.manual_seed(1)
    actor = sac.Actor(4, 3, (16,), -5.0, 2.0)
    obs = torch.randn(64, 4)
    gen = torch.Generator().manual_seed(0)
    a, logp, mean_action = actor.sample(obs, generator=gen)
    mu, log_std = actor(obs)
    u = torch.atanh(a.clamp(-1 + 1e-6, 1 - 1e-6)).double()
    base = torch.distributions.Normal(mu.double(), log_std.exp().double())
    ref = base.log_prob(u).sum(-1) - torch.log(1 - torch.tanh(u) ** 2).sum(-1)
    # the 1e-6 in the library's log(1 - a^2 + 1e-6) bounds the difference
    assert torch.allclose(logp.double(), ref, atol=2e-3)
    assert (a.abs() < 1).all() and torch.equal(mean_action, torch.tanh(mu))
    assert (log_std >= -5.0).all() and (log_std <= 2.0).all()


TINY = sac.SACConfig(total_steps=2000, learning_starts=1950, batch_size=16, hidden=(8,),
                     log_every=1000, checkpoint_every=1000, eval_episodes=1, seed=3)


def test_a_resumed_run_ends_where_an_uninterrupted_one_does(tmp_path):
    torch.set_num_threads(1)
    whole = sac.train("cartpole", TINY)
    ckpt = tmp_path / "run.sac"
    first = sac.train("cartpole", TINY, checkpoint=ckpt, stop_after_seconds=0)
    assert not first["done"] and first["steps"] == 1000 and ckpt.exists()
    rest = sac.train("cartpole", TINY, checkpoint=ckpt)
    assert rest["done"] and rest["steps"] == 2000
    for (k, p), (_, q) in zip(whole["actor"].state_dict().items(),
                              rest["actor"].state_dict().items()):
        assert torch.equal(p, q), k
    assert [r["eval_return"] for r in whole["log"]] == [r["eval_return"] for r in rest["log"]]
    # the updates did happen: the actor moved from its initialisation
    torch.manual_seed(TINY.seed)
    start = sac.Actor(5, 1, TINY.hidden, TINY.log_std_min, TINY.log_std_max)
    assert not torch.equal(start.mu.weight, whole["actor"].mu.weight)


def test_a_checkpoint_of_another_config_is_refused(tmp_path):
    ckpt = tmp_path / "run.sac"
    sac.train("cartpole", TINY, checkpoint=ckpt, stop_after_seconds=0)
    with pytest.raises(ValueError, match="another configuration"):
        sac.train("cartpole", dataclasses.replace(TINY, q_lr=2e-3), checkpoint=ckpt)


@pytest.mark.parametrize("field, value", [("total_steps", 0), ("batch_size", True),
                                          ("q_lr", float("inf")), ("gamma", 1.0),
                                          ("hidden", (0,)), ("learning_starts", 10)])
def test_bad_settings_are_refused_at_construction(field, value):
    with pytest.raises(ValueError, match=field):
        sac.SACConfig(**{field: value})


def test_checkpoints_fall_between_episodes():
    with pytest.raises(ValueError, match="horizon"):
        sac.train("cartpole", dataclasses.replace(TINY, checkpoint_every=1500))


def test_a_training_only_termination_ends_episodes_and_cuts_the_bootstrap(tmp_path):
    from dc_lesson import tasks
    from dc_lesson.nn.checkpoint import load_checked
    torch.set_num_threads(1)
    cfg = dataclasses.replace(TINY, terminate="hopper-fall")
    out = sac.train("hopper", cfg, checkpoint=tmp_path / "h.sac")
    assert out["done"] and out["steps"] == cfg.total_steps
    st = load_checked(tmp_path / "h.sac", sac.CHECKPOINT_FORMAT, sac.CHECKPOINT_VERSION, "x")
    done = st["buffer"]["done"].numpy()
    fell = tasks.TERMINATIONS["hopper-fall"](st["buffer"]["next_obs"].numpy())
    # random actions topple the hopper: episodes end at the fall, which is marked terminal,
    # and only there (a run ignoring the test would store 2 episodes and no terminal)
    assert done.sum() >= 5 and np.array_equal(done == 1, fell)
    with pytest.raises(ValueError, match="terminate must be one of"):
        sac.SACConfig(terminate="walker-fall")
