"""The SAC expert trainer: its pieces against their definitions, resume bit for bit, and its
refusals. (Whether it learns is measured by the stored expert runs, not here: a SAC run that
learns a locomotion task costs hours on this machine.)"""

import dataclasses

import numpy as np
import pytest
import torch

from dc_lesson.experts import sac

EPS32 = float(np.finfo(np.float32).eps)


@pytest.mark.parametrize("layer_norm", [False, True])
def test_twin_q_is_two_independent_mlps(layer_norm):
    torch.manual_seed(0)
    q = sac.TwinQ(5, (7, 3), layer_norm=layer_norm)
    obs, act = torch.randn(11, 3), torch.randn(11, 2)
    out = q(obs, act)
    assert out.shape == (2, 11)
    x = torch.cat([obs, act], -1)
    for k in range(2):   # member k by plain matrix products of its own weights
        h = x
        for i, (w, b) in enumerate(zip(q.weights, q.biases)):
            h = h @ w[k] + b[k]
            if i < len(q.weights) - 1:
                if layer_norm:   # each row's units to mean 0, variance 1 (biased, eps 1e-5)
                    h = (h - h.mean(-1, keepdim=True)) / torch.sqrt(
                        h.var(-1, unbiased=False, keepdim=True) + 1e-5)
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


def test_a_finished_run_extended_ends_where_a_longer_run_does(tmp_path):
    """total_steps only says where a run stops: a finished run resumed with more steps is the
    uninterrupted longer run, bit for bit; fewer steps than the checkpoint holds are refused."""
    torch.set_num_threads(1)
    longer = dataclasses.replace(TINY, total_steps=3000)
    whole = sac.train("cartpole", longer)
    ckpt = tmp_path / "run.sac"
    assert sac.train("cartpole", TINY, checkpoint=ckpt)["done"]
    rest = sac.train("cartpole", longer, checkpoint=ckpt)
    assert rest["done"] and rest["steps"] == 3000
    for (k, p), (_, q) in zip(whole["actor"].state_dict().items(),
                              rest["actor"].state_dict().items()):
        assert torch.equal(p, q), k
    assert [r["eval_return"] for r in whole["log"]] == [r["eval_return"] for r in rest["log"]]
    with pytest.raises(ValueError, match="past total_steps = 2000"):
        sac.train("cartpole", TINY, checkpoint=ckpt)


def test_a_checkpoint_of_another_config_is_refused(tmp_path):
    ckpt = tmp_path / "run.sac"
    sac.train("cartpole", TINY, checkpoint=ckpt, stop_after_seconds=0)
    with pytest.raises(ValueError, match="another configuration"):
        sac.train("cartpole", dataclasses.replace(TINY, q_lr=2e-3), checkpoint=ckpt)


@pytest.mark.parametrize("field, value", [("total_steps", 0), ("batch_size", True),
                                          ("q_lr", float("inf")), ("gamma", 1.0),
                                          ("hidden", (0,)), ("learning_starts", 10),
                                          ("demo_fraction", -0.1), ("critic_layer_norm", 1),
                                          ("demo_starts", 1.5)])
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


def _demos(reward: float, n: int = 2):
    """Cartpole episodes of a zero-action policy whose every step pays ``reward``."""
    from dc_lesson.data import rollout
    trajs = rollout.collect("cartpole", lambda obs: np.zeros((len(obs), 1)), n, seed=5,
                            progress=False)
    return [dataclasses.replace(t, rewards=np.full(len(t), reward)) for t in trajs]


def test_the_demonstration_buffer_holds_each_episode_s_transitions_in_order():
    demos = _demos(1.0)
    buf = sac.demo_buffer("cartpole", demos)
    T = len(demos[0])
    assert len(buf["obs"]) == len(buf["next_obs"]) == 2 * T and not buf["done"].any()
    np.testing.assert_array_equal(buf["next_obs"][:T - 1], buf["obs"][1:T])   # within one
    np.testing.assert_array_equal(buf["obs"][T], demos[1].observations[0])    # next episode
    np.testing.assert_array_equal(buf["act"][T:], demos[1].actions)
    with pytest.raises(ValueError, match="must be hopper trajectories"):
        sac.demo_buffer("hopper", demos)


DEMO = dataclasses.replace(TINY, learning_starts=1000, demo_fraction=0.5)
MIN_Q_GAP = 2.0   # value units; one step of the richer demonstrations pays 10


def test_the_critic_learns_the_demonstrations_rewards(tmp_path):
    """Two runs alike but for what the demonstrations pay (0 or 10 per step): the critic's
    value at the demonstrated pairs must tell them apart by several units. A loop that never
    samples the demonstrations (or drops their rewards) leaves the two critics together."""
    from dc_lesson.nn.checkpoint import load_checked
    torch.set_num_threads(1)
    q_mean = {}
    for reward in (0.0, 10.0):
        demos = _demos(reward)
        sac.train("cartpole", DEMO, checkpoint=tmp_path / f"{reward}.sac", demonstrations=demos)
        st = load_checked(tmp_path / f"{reward}.sac", sac.CHECKPOINT_FORMAT,
                          sac.CHECKPOINT_VERSION, "x")
        qf = sac.TwinQ(5 + 1, DEMO.hidden)
        qf.load_state_dict(st["qf"])
        buf = sac.demo_buffer("cartpole", demos)
        with torch.no_grad():
            q = qf(torch.from_numpy(buf["obs"]), torch.from_numpy(buf["act"]))
        q_mean[reward] = q.mean().item()
    assert q_mean[10.0] - q_mean[0.0] > MIN_Q_GAP, q_mean


def test_demonstrations_are_required_exactly_with_a_demo_field():
    with pytest.raises(ValueError, match="demo_fraction"):
        sac.train("cartpole", DEMO)
    with pytest.raises(ValueError, match="demo_fraction"):
        sac.train("cartpole", TINY, demonstrations=_demos(1.0))
    with pytest.raises(ValueError, match="demo_fraction"):
        sac.SACConfig(demo_fraction=1.0)


@pytest.mark.parametrize("cfg", [DEMO, dataclasses.replace(DEMO, demo_fraction=0.0,
                                                           critic_layer_norm=True,
                                                           demo_starts=0.5)],
                         ids=["demo minibatches", "demo starts (the humanoid's shape)"])
def test_a_run_with_demonstrations_resumes_bit_for_bit_and_keeps_them(tmp_path, cfg):
    torch.set_num_threads(1)
    whole = sac.train("cartpole", cfg, demonstrations=_demos(1.0))
    ckpt = tmp_path / "d.sac"
    sac.train("cartpole", cfg, checkpoint=ckpt, stop_after_seconds=0,
              demonstrations=_demos(1.0))
    with pytest.raises(ValueError, match="other demonstrations"):
        sac.train("cartpole", cfg, checkpoint=ckpt, demonstrations=_demos(2.0))
    rest = sac.train("cartpole", cfg, checkpoint=ckpt, demonstrations=_demos(1.0))
    assert rest["done"]
    for (k, p), (_, q) in zip(whole["actor"].state_dict().items(),
                              rest["actor"].state_dict().items()):
        assert torch.equal(p, q), k


def test_demonstrated_states_replay_to_the_demonstrated_observations():
    from dc_lesson import tasks
    demos = _demos(1.0)
    states = sac.demo_states("cartpole", demos)
    T = len(demos[0])
    assert states.shape[0] == 2 * T
    env = tasks.make("cartpole")
    for i, k in ((0, 0), (0, T - 1), (1, 123)):
        env.reset(seed=0)
        obs = env.set_state(states[i * T + k])
        np.testing.assert_allclose(obs, demos[i].observations[k], rtol=0, atol=1e-9)


def test_demo_starts_begin_training_episodes_at_demonstrated_states(tmp_path):
    """With ``demo_starts`` 1 each training episode's first observation is a demonstrated one;
    with 0 (the default) none is: the task's own starts never coincide with them."""
    from dc_lesson import tasks
    from dc_lesson.nn.checkpoint import load_checked
    torch.set_num_threads(1)
    demos = _demos(1.0)
    shown = np.concatenate([t.observations[:-1] for t in demos])
    firsts = {}
    for share in (0.0, 1.0):
        cfg = dataclasses.replace(DEMO, demo_starts=share)
        sac.train("cartpole", cfg, checkpoint=tmp_path / f"{share}.sac", demonstrations=demos)
        st = load_checked(tmp_path / f"{share}.sac", sac.CHECKPOINT_FORMAT,
                          sac.CHECKPOINT_VERSION, "x")
        obs = st["buffer"]["obs"].numpy()
        firsts[share] = obs[::tasks.spec("cartpole").horizon]
    for share, expect in ((0.0, False), (1.0, True)):
        hits = [bool(np.any(np.all(np.abs(shown - o) < 1e-9, axis=1))) for o in firsts[share]]
        assert hits == [expect] * len(hits), (share, hits)
    with pytest.raises(ValueError, match="demo_starts"):
        sac.train("cartpole", dataclasses.replace(TINY, demo_starts=0.5))
