"""GAIL: the discriminator learns and its reward prefers the expert, the reward forms by hand,
GAIL beats a random policy on cartpole (permutation test), determinism, exact resume from a
checkpoint (one written before GAIL moved onto the shared loop too), the frozen normaliser, clear
errors, and the benchmark's small pieces."""

import copy
import dataclasses
import math
import time

import numpy as np
import pytest
import torch

from dc_lesson.experiments import gail as gail_runs
from dc_lesson import data
from dc_lesson.algorithms import gail, ppo
from dc_lesson.data import rollout
from dc_lesson.nn.policies import GaussianPolicy, PolicyFileError

TIMING = {"steps_per_second"}


def _three(r):
    """(policy, discriminator, log) of a TrainResult."""
    return r.policy, r.models["discriminator"], r.log


def _pairs(trajectories):
    obs = np.concatenate([t.observations[:-1] for t in trajectories]).astype(np.float32)
    act = np.concatenate([t.actions for t in trajectories]).astype(np.float32)
    return torch.from_numpy(obs), torch.from_numpy(act)


def _random_pairs(task, n_episodes, seed):
    trajs = rollout.collect(task, rollout.RandomPolicy(task, seed=seed), n_episodes, seed=seed,
                            progress=False)
    return _pairs(trajs)


# -- the discriminator and its reward ------------------------------------------------------------

def test_reward_forms_match_their_formulas():
    f = torch.linspace(-30, 30, 61)
    d = torch.sigmoid(f.double())
    mid = slice(20, 41)   # where 1 - D is representable in float64
    torch.testing.assert_close(gail.reward_from_logit(f, "gail")[mid].double(),
                               -torch.log1p(-d)[mid], rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(gail.reward_from_logit(f, "log_d").double(), torch.log(d),
                               rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(gail.reward_from_logit(f, "logit"), f)
    # The default reward is positive, rises with D and is finite even where D rounds to 1.
    r = gail.reward_from_logit(f, "gail")
    assert torch.all(r > 0) and torch.all(r[1:] > r[:-1]) and torch.isfinite(r).all()
    with pytest.raises(ValueError, match="reward form"):
        gail.reward_from_logit(f, "wgan")


def test_discriminator_loss_falls_and_its_reward_prefers_expert_pairs():
    e_obs, e_act = _pairs(data.load_demos("reacher1", n_trajectories=4).trajectories)
    l_obs, l_act = _random_pairs("reacher1", 2, seed=5)           # the fixed learner batch
    torch.manual_seed(0)
    disc = gail.Discriminator(e_obs.shape[1], e_act.shape[1])
    disc.fit_input_stats(e_obs, e_act)
    opt = torch.optim.Adam(disc.parameters(), lr=1e-3)
    g = torch.Generator().manual_seed(0)
    with torch.no_grad():
        before = gail.discriminator_loss(disc, e_obs, e_act, l_obs, l_act)
    for _ in range(300):
        ie = torch.randint(len(e_obs), (256,), generator=g)
        il = torch.randint(len(l_obs), (256,), generator=g)
        gail.discriminator_step(disc, opt, e_obs[ie], e_act[ie], l_obs[il], l_act[il])
    with torch.no_grad():
        after = gail.discriminator_loss(disc, e_obs, e_act, l_obs, l_act)
    print(f"\ndiscriminator BCE {float(before['bce']):.3f} -> {float(after['bce']):.3f}; "
          f"accuracy expert {float(after['acc_expert']):.2f}, learner "
          f"{float(after['acc_learner']):.2f}")
    assert float(before["bce"]) > 1.2                       # about 2 log 2 at the start
    assert float(after["bce"]) < 0.5 * float(before["bce"])
    assert float(after["acc_expert"]) > 0.8 and float(after["acc_learner"]) > 0.8
    # On pairs it never saw: held-out expert demonstrations and fresh random-policy episodes.
    he_obs, he_act = _pairs(data.load_demos("reacher1").trajectories[10:14])
    hr_obs, hr_act = _random_pairs("reacher1", 2, seed=77)
    with torch.no_grad():
        r_expert = gail.reward_from_logit(disc(he_obs, he_act)).mean()
        r_random = gail.reward_from_logit(disc(hr_obs, hr_act)).mean()
    print(f"reward on held-out expert pairs {float(r_expert):.3f}, on random pairs "
          f"{float(r_random):.3f}")
    assert r_expert > 2 * r_random


def test_discriminator_sees_clipped_standardised_actions_and_the_penalty_is_used():
    torch.manual_seed(0)
    disc = gail.Discriminator(3, 2)
    obs, act = torch.randn(100, 3) * 4 + 1, torch.rand(100, 2) * 2 - 1
    disc.fit_input_stats(obs, act)
    x = disc.inputs(obs, act)
    torch.testing.assert_close(x.mean(0), torch.zeros(5), atol=1e-5, rtol=0)
    torch.testing.assert_close(x.std(0), torch.ones(5), atol=1e-5, rtol=0)
    # An action beyond the bounds is scored as the action the environment applies.
    torch.testing.assert_close(disc(obs[:3], torch.full((3, 2), 7.0)),
                               disc(obs[:3], torch.ones(3, 2)))
    plain = gail.discriminator_loss(disc, obs, act, obs + 1, act)
    pen = gail.discriminator_loss(disc, obs, act, obs + 1, act, grad_penalty=10.0,
                                  generator=torch.Generator().manual_seed(0))
    assert float(plain["penalty"]) == 0 and float(pen["penalty"]) > 0
    torch.testing.assert_close(pen["loss"], pen["bce"] + 10.0 * pen["penalty"])


# -- runs ----------------------------------------------------------------------------------------

def _tiny(seed=3, total_steps=512, **kw):
    p = ppo.PPOConfig(n_envs=2, n_steps=64, n_epochs=2, n_minibatches=4,
                      total_steps=total_steps)
    return gail.GAILConfig(ppo=p, disc_steps=2, disc_batch=64, value_warmup=1, seed=seed, **kw)


def _same_log(a, b):
    np.testing.assert_equal([{k: v for k, v in r.items() if k not in TIMING} for r in a],
                            [{k: v for k, v in r.items() if k not in TIMING} for r in b])


def _same_state(a, b):
    sa, sb = a.state_dict(), b.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k


@pytest.fixture(scope="module")
def demos1():
    return data.load_demos("reacher1", n_trajectories=3)


def test_same_seed_same_gail_run(demos1):
    runs = [_three(gail.train("reacher1", demos1, _tiny(), progress=False)) for _ in range(2)]
    other = _three(gail.train("reacher1", demos1, _tiny(seed=4), progress=False))
    _same_log(runs[0][2], runs[1][2])
    _same_state(runs[0][0], runs[1][0])
    _same_state(runs[0][1], runs[1][1])
    assert len(runs[0][2]) == 4 and runs[0][2][0]["policy_frozen"]
    assert not torch.equal(runs[0][0].mean_net[0].weight, other[0].mean_net[0].weight)
    for key in ("disc_loss", "acc_expert", "acc_learner", "reward_mean", "reward_std",
                "steps_per_second", "episode_return", "policy_loss"):
        assert key in runs[0][2][0]


def test_checkpoint_resume_equals_an_uninterrupted_run(demos1, tmp_path):
    # 1000-step horizon, 2 x 64 steps per iteration: 10 iterations cross an episode end, and the
    # stop after iteration 3 falls mid-episode (the environments are restored by replay).
    cfg = _tiny(total_steps=1280)
    full_pi, full_d, full_log = _three(gail.train("reacher1", demos1, cfg, progress=False))
    path = tmp_path / "gail.ckpt"
    gail.train("reacher1", demos1, cfg, progress=False, checkpoint=path, checkpoint_every=1,
               callback=lambda row, pi: row["update"] == 3)
    pi, d, log = _three(gail.train("reacher1", demos1, cfg, progress=False, checkpoint=path))
    _same_log(full_log, log)
    _same_state(full_pi, pi)
    _same_state(full_d, d)
    # A checkpoint of another configuration is refused, naming the difference.
    with pytest.raises(PolicyFileError, match="disc_lr"):
        gail.train("reacher1", demos1, dataclasses.replace(cfg, disc_lr=1e-3), progress=False,
                   checkpoint=path)


# The entries of a GAIL checkpoint written before GAIL ran on _reward_ppo.run (b6662dd and
# earlier): the loop writes the same ones plus ``state``, a learner's other state (GAIL has none).
OLD_CHECKPOINT = ["config", "disc", "disc_args", "disc_generator", "disc_optimizer", "envs",
                  "format", "generator", "log", "optimizer", "policy", "policy_args", "task",
                  "update", "value", "value_args", "version"]


def test_a_checkpoint_from_before_the_shared_loop_resumes_exactly(demos1, tmp_path):
    from dc_lesson.nn.checkpoint import atomic_torch_save
    cfg = _tiny(total_steps=768, expert_noise="learner", grad_penalty=1.0)
    full_pi, full_d, full_log = _three(gail.train("reacher1", demos1, cfg, progress=False))
    path = tmp_path / "old.ckpt"
    gail.train("reacher1", demos1, cfg, progress=False, checkpoint=path, checkpoint_every=1,
               callback=lambda row, pi: row["update"] == 2)
    ckpt = torch.load(path, weights_only=True)
    assert ckpt.pop("state") == {} and sorted(ckpt) == OLD_CHECKPOINT
    assert (ckpt["format"], ckpt["version"]) == ("dc_lesson.gail.checkpoint", 1)
    atomic_torch_save(ckpt, path)                  # the old layout, with its checksum
    pi, d, log = _three(gail.train("reacher1", demos1, cfg, progress=False, checkpoint=path))
    _same_log(full_log, log)
    _same_state(full_pi, pi)
    _same_state(full_d, d)


def test_the_discriminator_is_drawn_after_the_critic_from_the_init_seed():
    """The order of the initialisation's draws (policy, critic, then D) that GAIL's stored
    cells were made with, now that the shared loop's make_networks builds them."""
    from dc_lesson import tasks
    from dc_lesson.algorithms import _reward_ppo
    from dc_lesson.nn.policies import ValueNetwork
    spec, pcfg = tasks.spec("reacher1"), ppo.PPOConfig()
    e_obs = torch.randn(50, spec.obs_dim)
    pi, value, disc = _reward_ppo.make_networks(
        spec, pcfg, e_obs, None, 11, lambda: gail.Discriminator(spec.obs_dim, spec.act_dim))
    torch.manual_seed(11)
    GaussianPolicy(spec.obs_dim, spec.act_dim, pcfg.hidden, log_std_init=pcfg.log_std_init,
                   norm_obs=pcfg.norm_obs)
    ValueNetwork(spec.obs_dim, pcfg.hidden, norm_obs=pcfg.norm_obs)
    _same_state(gail.Discriminator(spec.obs_dim, spec.act_dim), disc)


def test_gail_keeps_nn_fast_s_adamw_for_the_policy_and_critic(demos1, monkeypatch):
    """GAIL's cells were made with nn.fast.adamw, fused on the fast path (not the bits of
    torch's AdamW, which the shared loop gives DRIL, PWIL and NDI); GAIL keeps it."""
    from dc_lesson.nn import fast
    built, real = [], fast.adamw
    monkeypatch.setattr(fast, "adamw", lambda *a, **k: built.append(real(*a, **k)) or built[-1])
    with fast.on():
        gail.train("reacher1", demos1, _tiny(), progress=False, callback=lambda row, pi: True)
    assert len(built) == 1 and [g["fused"] for g in built[0].param_groups] == [True, True]


def test_the_warm_start_normaliser_stays_frozen(demos1):
    from dc_lesson.algorithms import bc
    policy, demos, _ = bc.warm_start("reacher1", 3, seed=0, max_epochs=2)
    before = {k: v.clone() for k, v in policy.state_dict().items()}
    trained, _, _ = _three(gail.train("reacher1", demos, _tiny(), policy=policy, progress=False))
    assert trained is policy
    after = trained.state_dict()
    for k in ("obs_norm.mean", "obs_norm.var", "obs_norm.count"):
        assert torch.equal(after[k], before[k]), k
    # The weights did move: the policy was trained, its inputs' scale was not changed.
    assert not torch.equal(after["mean_net.0.weight"], before["mean_net.0.weight"])


def test_a_given_start_explores_with_start_log_std(demos1):
    from dc_lesson.algorithms import bc
    start, demos, _ = bc.warm_start("reacher1", 3, seed=0, max_epochs=2)
    assert torch.allclose(start.log_std, torch.tensor(bc.WARM_START_LOG_STD))
    seen = {}
    for value in (-2.0, None):
        stds = []
        gail.train("reacher1", demos, _tiny(start_log_std=value), policy=copy.deepcopy(start),
                   progress=False, callback=lambda row, pi: stds.append(pi.log_std.clone())
                   or True)   # stop after iteration 0, the value warm-up (policy frozen)
        seen[value] = stds[0]
    assert torch.equal(seen[-2.0], torch.full_like(seen[-2.0], -2.0))
    assert torch.equal(seen[None], start.log_std.detach())
    # the default keeps a start's noise; the presets (the cell studies) set the tuned value
    assert gail.GAILConfig().start_log_std is None
    from dc_lesson import budget
    assert gail.preset(budget.get("lesson")).start_log_std == gail.TUNED_START_LOG_STD == -2.0
    # a fresh policy keeps PPO's initial log-std: the knob is about a warm start's noise
    fresh = []
    gail.train("reacher1", demos, _tiny(start_log_std=-2.0), progress=False,
               callback=lambda row, pi: fresh.append(pi.log_std.clone()) or True)
    assert torch.allclose(fresh[0], torch.tensor(ppo.PPOConfig().log_std_init))


def test_clear_errors_for_bad_configurations(demos1):
    with pytest.raises(ValueError, match="reward_form"):
        gail.GAILConfig(reward_form="wasserstein")
    with pytest.raises(ValueError, match="disc_steps"):
        gail.GAILConfig(disc_steps=0)
    with pytest.raises(ValueError, match="disc_lr"):
        gail.GAILConfig(disc_lr=0.0)
    with pytest.raises(ValueError, match="grad_penalty"):
        gail.GAILConfig(grad_penalty=-1.0)
    with pytest.raises(ValueError, match="value_warmup"):
        dataclasses.replace(_tiny(), value_warmup=4)     # 4 iterations in all
    with pytest.raises(TypeError, match="PPOConfig"):
        gail.GAILConfig(ppo={"lr": 1e-3})
    with pytest.raises(ValueError, match="learning rate"):
        gail.GAILConfig().with_lr(-1e-3)
    with pytest.raises(ValueError, match="demonstrations are of 'reacher1', not 'cartpole'"):
        gail.train("cartpole", demos1, _tiny(), progress=False)       # reacher demos
    with pytest.raises(ValueError, match="policy"):
        gail.train("reacher1", demos1, _tiny(), policy=GaussianPolicy(5, 1), progress=False)


def test_with_lr_sets_every_learning_rate():
    cfg = gail.GAILConfig().with_lr(3e-3)
    assert cfg.ppo.lr == cfg.disc_lr == 3e-3 and cfg.ppo_config.lr == 3e-3
    assert gail.GAILConfig(seed=5, entropy=0.01).ppo_config.seed == 5
    assert gail.GAILConfig(entropy=0.01).ppo_config.ent_coef == 0.01


# -- GAIL learns ---------------------------------------------------------------------------------

# GAIL from scratch (no BC warm start, so the gain is GAIL's own) on cartpole: PPO's cartpole
# settings from tests/test_ppo.py (no observation normaliser, lr 3e-3, gamma 0.98), 4
# demonstrations as the expert's pairs, 60k interactions in training episodes cut at 200
# steps (measured: about 55 s, evaluation return 776 ± 101 against the random policy's ~356).
# With the full 1000-step episodes the same run stayed at the random policy's level (321):
# the discriminator won outright (accuracy 1.00 / 0.98), with or without a gradient penalty,
# a log D reward or a weaker discriminator; short episodes give it many more starts to learn
# balancing from, where the expert's and the learner's states still overlap.
LEARN = gail.GAILConfig(
    ppo=ppo.PPOConfig(n_envs=8, n_steps=250, n_epochs=10, n_minibatches=8, lr=3e-3,
                      gamma=0.98, norm_obs=False, total_steps=60_000, episode_steps=200),
    disc_lr=1e-3, value_warmup=0, bc_warm_start=False, seed=0)
MIN_GAIN = 250.0   # return over the random policy's (~350), on the 0..1000 scale


def test_gail_improves_over_the_random_policy_on_cartpole():
    from scipy import stats
    start = time.perf_counter()
    demos = data.load_demos("cartpole", n_trajectories=4)
    policy, _, log = _three(gail.train("cartpole", demos, LEARN, progress=False))
    trained_s = time.perf_counter() - start
    learned = rollout.returns(rollout.collect("cartpole", policy, 10, seed=2024,
                                              progress=False))
    random = rollout.returns(rollout.collect("cartpole", rollout.RandomPolicy("cartpole", 0),
                                             10, seed=2024, progress=False))
    test = stats.permutation_test((learned, random),
                                  lambda x, y, axis: x.mean(axis) - y.mean(axis),
                                  permutation_type="independent", alternative="greater",
                                  n_resamples=9999, vectorized=True, rng=0)
    gain = learned.mean() - random.mean()
    print(f"\nGAIL cartpole: {LEARN.ppo.total_steps} steps in {trained_s:.0f} s; learned "
          f"{learned.mean():.0f} ± {learned.std():.0f}, random {random.mean():.0f}; gain "
          f"{gain:.0f}; p = {test.pvalue:.4f}; final discriminator accuracy expert "
          f"{log[-1]['acc_expert']:.2f}, learner {log[-1]['acc_learner']:.2f}")
    assert all(math.isfinite(r["disc_loss"]) for r in log)
    assert test.pvalue < 0.05
    assert gain >= MIN_GAIN


# GAIL from scratch (no BC start) on cartpole, issue 38's second learning test: LEARN at lr 1e-3
# for 300,000 interactions, 3 seeds, the mean-action scaled return at 5 checkpoints. Measured
# when written (5 December, one thread): final 0.99 / 0.99 / 1.00 on seeds 0-2 (0.55 on seed
# 3); at LEARN's lr 3e-3, 0.81 / 0.99 / 1.00. GAIL's curve is not monotone, so the claim is
# "reaches 0.9", at some checkpoint, on every seed; keeping it is the competence study's.
SCRATCH_STEPS, SCRATCH_SEEDS, SCRATCH_FLOOR = 300_000, (0, 1, 2), 0.9


def test_gail_from_scratch_learns_cartpole_to_the_expert_s_level():
    from dc_lesson.evaluation import CheckpointCurve, evaluate_policy
    demos = data.load_demos("cartpole", n_trajectories=4)
    best = []
    for seed in SCRATCH_SEEDS:
        cfg = dataclasses.replace(LEARN, seed=seed, ppo=dataclasses.replace(
            LEARN.ppo, lr=1e-3, total_steps=SCRATCH_STEPS))
        curve = CheckpointCurve(lambda p: evaluate_policy(
            "cartpole", p, None, n_episodes=5, seed=2024, divergences=False), SCRATCH_STEPS, 5)
        gail.train("cartpole", demos, cfg, progress=False, callback=curve)
        best.append(max(pt["scaled_return"] for pt in curve.points))
    assert min(best) >= SCRATCH_FLOOR, f"best checkpoint per seed: {np.round(best, 3)}"


# -- the study's config ----------------------------------------------------------------------

def test_the_study_config_scales_down_for_smoke_runs():
    cfg = gail_runs.gail_config(4096, seed=2)
    assert cfg.ppo.n_updates >= 4 and cfg.value_warmup < cfg.ppo.n_updates and cfg.seed == 2
    full = gail_runs.gail_config(300_000, seed=1, lr=1e-3)
    assert full.ppo.batch_size == gail.GAILConfig().ppo.batch_size
    assert full.ppo.lr == full.disc_lr == 1e-3 and full.ppo.total_steps == 300_000


def test_a_state_only_discriminator_ignores_actions(demos1):
    """disc_actions=False: D(s) gives the same logit for any action, so the learner's action
    noise cannot give it away; the run trains and repeats for its seed."""
    disc = gail.Discriminator(8, 2, (16,), use_actions=False)
    obs = torch.randn(10, 8)
    assert torch.equal(disc(obs, torch.zeros(10, 2)), disc(obs, torch.ones(10, 2)))
    cfg = dataclasses.replace(_tiny(), disc_actions=False)
    a = gail.train("reacher1", demos1, cfg, progress=False)
    b = gail.train("reacher1", demos1, cfg, progress=False)
    assert a.models["discriminator"].config()["use_actions"] is False
    _same_state(a.policy, b.policy)


def test_expert_noise_gives_the_expert_the_learner_s_spread_and_nothing_else():
    torch.manual_seed(0)
    pi = GaussianPolicy(3, 2, (8,), log_std_init=-2.0)
    with torch.no_grad():
        pi.log_std.copy_(torch.tensor([-2.0, -1.0]))
    acts = torch.full((20000, 2), 0.3)
    assert gail.expert_actions(acts, pi, gail.GAILConfig(), torch.Generator()) is acts
    cfg = gail.GAILConfig(expert_noise="learner")
    seen = gail.expert_actions(acts, pi, cfg, torch.Generator().manual_seed(1))
    # centred on the recorded actions, each dimension spread by the learner's own std
    np.testing.assert_allclose(seen.mean(0), [0.3, 0.3], atol=0.01)
    np.testing.assert_allclose(seen.std(0), np.exp([-2.0, -1.0]), rtol=0.03)
    again = gail.expert_actions(acts, pi, cfg, torch.Generator().manual_seed(1))
    assert torch.equal(seen, again)                          # drawn from the run's generator
    # a later knob: unset, stored GAIL cells keep their identity; set, it is in the JSON
    assert "expert_noise" not in gail.GAILConfig().to_json()
    assert '"expert_noise": "learner"' in cfg.to_json()
    with pytest.raises(ValueError, match="expert_noise"):
        gail.GAILConfig(expert_noise="expert")


def test_expert_noise_refuses_a_policy_without_one_spread(demos1):
    from dc_lesson.nn.mixture import MixturePolicy
    mix = MixturePolicy(8, 2, n_components=2)
    with pytest.raises(ValueError, match="mixture"):
        gail.train("reacher1", demos1, _tiny(expert_noise="learner"), policy=mix,
                   progress=False)
