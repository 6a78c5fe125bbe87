"""DRIL, PWIL, NDI and GPRIL: each algebraic piece against a direct computation (DRIL's quantile
rule on a constructed ensemble, PWIL's greedy coupling against exact optimal transport and its
reward, NDI's reward on a Gaussian whose log-density is known and its kNN entropy, GPRIL's
horizon distribution, its predecessor sampler and its flow's log-density against a brute-force
Jacobian), then determinism and exact resume of each through its ``train``."""

import dataclasses
import math

import numpy as np
import ot
import pytest
import torch

from dc_lesson import data
from dc_lesson.algorithms import dril, gpril, ndi, ppo, pwil
from dc_lesson.algorithms.dc import RewardScale
from dc_lesson.nn.policies import PolicyFileError
from test_gail import _same_log, _same_state   # logs equal but for timing; state_dicts equal


# -- DRIL ----------------------------------------------------------------------------------------

class _Linear:
    """A constructed ensemble member: mu(s) = s @ W (no training)."""

    def __init__(self, w):
        self.w = torch.as_tensor(w, dtype=torch.float32)

    def __call__(self, obs):
        return obs @ self.w


def test_dril_cost_is_the_ensemble_covariance_along_the_action():
    g = torch.Generator().manual_seed(0)
    members = [_Linear(0.3 * torch.randn(3, 2, generator=g)) for _ in range(5)]
    obs = torch.randn(50, 3, generator=g) * 0.5
    act = torch.rand(50, 2, generator=g) * 2 - 1
    cost = dril.disagreement(members, obs, act)
    for i in range(0, 50, 7):
        mu = np.stack([np.clip(m(obs[i]).numpy(), -1, 1) for m in members])   # (E, A)
        a = act[i].numpy()
        assert cost[i] == pytest.approx(a @ np.cov(mu.T) @ a, rel=1e-4, abs=1e-7)
    # Members that agree cost nothing; actions are scored as applied (clipped).
    same = [_Linear(torch.ones(3, 2))] * 3
    assert torch.all(dril.disagreement(same, obs, act) < 1e-10)
    torch.testing.assert_close(dril.disagreement(members, obs, 7 * act.sign()),
                               dril.disagreement(members, obs, act.sign()))


def test_dril_reward_is_plus_one_up_to_the_expert_quantile_and_minus_one_above():
    g = torch.Generator().manual_seed(1)
    members = [_Linear(torch.randn(2, 1, generator=g)) for _ in range(4)]
    e_obs = torch.randn(1000, 2, generator=g) * 0.2
    e_act = torch.rand(1000, 1, generator=g) * 2 - 1
    costs = dril.disagreement(members, e_obs, e_act).numpy()
    q = dril.cost_threshold(members, e_obs, e_act, 0.98)
    assert q == pytest.approx(np.quantile(costs, 0.98))
    r = dril.dril_reward(torch.as_tensor(costs), q)
    assert set(r.unique().tolist()) == {-1.0, 1.0}
    assert float((r > 0).float().mean()) == pytest.approx(0.98, abs=0.002)
    torch.testing.assert_close(r, torch.where(torch.as_tensor(costs) <= q, 1.0, -1.0))
    assert dril.dril_reward(torch.tensor([q, q * 1.0001 + 1e-9]), q).tolist() == [1.0, -1.0]


# -- PWIL ----------------------------------------------------------------------------------------

def _emd(learner, expert):
    c = ot.dist(learner, expert, metric="euclidean")
    return ot.emd2(np.full(len(learner), 1 / len(learner)), np.full(len(expert), 1 / len(expert)),
                   c), c


def test_pwil_greedy_coupling_is_a_coupling_and_bounds_the_exact_transport():
    # 1-D, two steps: step 1 at 1.1 grabs the atom at 2 (nearer), leaving 3 the atom at 0;
    # the optimal plan sends 1.1 -> 0 and 3 -> 2.
    expert, learner = np.array([[0.0], [2.0]]), np.array([[1.1], [3.0]])
    costs, plan = pwil.greedy_coupling(learner, expert)
    np.testing.assert_allclose(costs, [0.45, 1.5])
    np.testing.assert_allclose(plan, [[0, 0.5], [0.5, 0]])
    exact, _ = _emd(learner, expert)
    assert exact == pytest.approx(1.05) and costs.sum() > exact + 0.5
    # Random cases with T != N: the plan has the right marginals, its cost is the sum of the
    # step costs and never below the exact optimum; a learner that retraces the expert's atoms
    # one by one pays exactly what the optimum pays (nothing).
    rng = np.random.default_rng(0)
    for T, N in ((3, 7), (7, 3), (5, 5)):
        learner, expert = rng.normal(size=(T, 2)), rng.normal(size=(N, 2))
        costs, plan = pwil.greedy_coupling(learner, expert)
        exact, c = _emd(learner, expert)
        np.testing.assert_allclose(plan.sum(1), 1 / T, atol=1e-12)
        np.testing.assert_allclose(plan.sum(0), 1 / N, atol=1e-12)
        assert costs.sum() == pytest.approx((plan * c).sum())
        assert costs.sum() >= exact - 1e-12
    costs, _ = pwil.greedy_coupling(expert[::-1], expert)
    assert costs.sum() == pytest.approx(_emd(expert[::-1], expert)[0], abs=1e-12) == 0


def test_pwil_reward_formula_and_per_environment_episodes_across_batches():
    assert pwil.pwil_reward([0.0], 1000, 10)[0] == pytest.approx(5.0)
    assert pwil.pwil_reward([0.002], 1000, 9, alpha=5, beta=5)[0] == pytest.approx(
        5 * math.exp(-5 * 1000 * 0.002 / 3))
    # Two environments, episodes of T = 4 steps fed as two batches of 3 steps: the costs are
    # those of the greedy coupling of each episode alone (state kept across the batches, reset
    # at the episode end), in the standardised space.
    rng = np.random.default_rng(3)
    atoms_raw = rng.normal(size=(6, 3))
    mean, std = atoms_raw.mean(0), atoms_raw.std(0)
    atoms = (atoms_raw - mean) / std
    T, n_envs = 4, 2
    rw = pwil.Rewarder(atoms, mean, std, T, n_envs, 5.0, 5.0, use_actions=True)
    obs = torch.as_tensor(rng.normal(size=(6, n_envs, 2)), dtype=torch.float32)
    act = torch.as_tensor(rng.uniform(-1, 1, size=(6, n_envs, 1)), dtype=torch.float32)
    dones = torch.zeros(6, n_envs, dtype=torch.bool)
    dones[T - 1] = True
    got = []
    for lo in (0, 3):
        batch = dataclasses.make_dataclass("B", ["obs", "actions", "dones"])(
            obs[lo:lo + 3], act[lo:lo + 3], dones[lo:lo + 3])
        got.append(rw.rewards(batch)[0].numpy())
    got = np.concatenate(got)
    for e in range(n_envs):
        x = (np.concatenate([obs[:, e].numpy(), act[:, e].numpy()], -1) - mean) / std
        first, _ = pwil.greedy_coupling(x[:T], atoms)
        want = pwil.pwil_reward(first, T, 3)
        np.testing.assert_allclose(got[:T, e], want, rtol=1e-5)
        # After the reset the next episode starts from every atom's full mass again.
        weights = np.full(len(atoms), 1 / len(atoms))
        for t in (T, T + 1):
            c = pwil.couple_step(np.linalg.norm(atoms - x[t], axis=1), weights, 1 / T)
            np.testing.assert_allclose(got[t, e], pwil.pwil_reward([c], T, 3)[0], rtol=1e-5)


# -- NDI -----------------------------------------------------------------------------------------

def test_ndi_reward_on_a_known_density():
    mean, cov = torch.tensor([0.5, -1.0, 0.2]), torch.tensor(
        [[1.0, 0.3, 0.0], [0.3, 2.0, 0.1], [0.0, 0.1, 0.5]])
    q = torch.distributions.MultivariateNormal(mean, cov)
    g = torch.Generator().manual_seed(0)
    obs, act = torch.randn(40, 2, generator=g), torch.rand(40, 1, generator=g) * 4 - 2
    x = torch.cat([obs, act.clamp(-1, 1)], -1).double()
    d = x - mean.double()
    analytic = -0.5 * (d @ torch.linalg.inv(cov.double()) * d).sum(-1) \
        - 0.5 * torch.logdet(cov.double()) - 1.5 * math.log(2 * math.pi)
    torch.testing.assert_close(ndi.log_density(q, obs, act).double(), analytic, rtol=1e-5,
                               atol=1e-5)
    scale = RewardScale(low=-10.0, high=-2.0)
    raw = ndi.Reward(q, None, 0.0, torch.zeros(2), torch.ones(2))
    scaled = ndi.Reward(q, scale, 0.0, torch.zeros(2), torch.ones(2))
    torch.testing.assert_close(raw(obs, act, obs)[0].double(), analytic, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(scaled(obs, act, obs)[0].double(),
                               ((analytic + 10) / 8).clamp(0, 1), rtol=1e-5, atol=1e-5)
    # The entropy bonus adds lambda * h_i of the (standardised) next states.
    nxt = torch.randn(40, 2, generator=g) * 3 + 1
    bonus = ndi.Reward(q, None, 0.1, torch.ones(2), 3 * torch.ones(2), k=3)
    h = ndi.knn_entropy_terms((nxt - 1) / 3, 3)
    torch.testing.assert_close(bonus(obs, act, nxt)[0].double(), analytic + 0.1 * h,
                               rtol=1e-5, atol=1e-5)


def test_knn_entropy_matches_a_gaussians_entropy():
    g = torch.Generator().manual_seed(0)
    for d, std in ((1, 1.0), (3, 0.5)):
        x = torch.randn(4000, d, generator=g, dtype=torch.float64) * std
        estimate = float(ndi.knn_entropy_terms(x, k=5).mean())
        exact = 0.5 * d * math.log(2 * math.pi * math.e * std ** 2)
        assert estimate == pytest.approx(exact, abs=0.05 * d), (d, estimate, exact)
    with pytest.raises(ValueError, match="more than 5 points"):
        ndi.knn_entropy_terms(torch.zeros(5, 2), k=5)


# -- GPRIL ---------------------------------------------------------------------------------------

def test_gpril_horizons_are_geometric():
    g = torch.Generator().manual_seed(0)
    for gamma in (0.5, 0.9):
        j = gpril.sample_horizons(200_000, gamma, g).double()
        mean, var = 1 / (1 - gamma), gamma / (1 - gamma) ** 2
        assert j.min() == 1
        assert float(j.mean()) == pytest.approx(mean, abs=4 * math.sqrt(var / len(j)))
        assert float(j.var()) == pytest.approx(var, rel=0.03)
        # P(j = 1) = 1 - gamma
        assert float((j == 1).double().mean()) == pytest.approx(1 - gamma, abs=0.005)


def test_gpril_predecessor_sampler_stays_in_one_episode_with_geometric_offsets():
    # The "state" of a step is (its time, its episode): the tuples' offsets can be read off.
    T, N = 3000, 2
    t = torch.arange(T, dtype=torch.float32)
    episode = (torch.arange(T) // 1000).repeat(N, 1).T          # episodes of 1000 steps
    obs = torch.stack([torch.stack([t, episode[:, 0].float()], -1)] * N, 1)
    buf = gpril.Buffer(T)
    buf.add(obs, torch.zeros(T, N, 1), episode)
    s, _, fut, j = gpril.sample_tuples(buf, 50_000, 0.9, torch.Generator().manual_seed(1))
    assert len(s) == 50_000
    torch.testing.assert_close(fut[:, 0] - s[:, 0], j.float())
    assert torch.equal(fut[:, 1], s[:, 1])                      # never across an episode end
    assert float(j.double().mean()) == pytest.approx(10.0, abs=0.15)
    assert float(j.double().var()) == pytest.approx(90.0, rel=0.05)


def test_gpril_maf_log_prob_is_the_change_of_variables():
    torch.manual_seed(0)
    flow = gpril.ConditionalMAF(3, 2, hidden=(16, 16), n_layers=3)
    for p in flow.parameters():                          # move away from the identity start
        torch.nn.init.normal_(p, std=0.3)
    flow.set_standardisation(torch.tensor([1.0, 0.0, -1.0]), torch.tensor([2.0, 0.5, 1.0]),
                             torch.tensor([0.0, 1.0]), torch.tensor([1.0, 3.0]))
    x, c = torch.randn(5, 3), torch.randn(5, 2)
    got = flow.log_prob(x, c).detach()
    for i in range(5):
        u_of = lambda xi: flow.to_base(xi[None], c[i:i + 1])[0][0]
        jac = torch.autograd.functional.jacobian(u_of, x[i])
        u = u_of(x[i])
        want = torch.distributions.Normal(0.0, 1.0).log_prob(u).sum() + torch.slogdet(jac)[1]
        assert float(got[i]) == pytest.approx(float(want.detach()), abs=1e-4)
    # Sampling inverts the map: x = sample(c) maps back to finite u, and the same noise.
    g = torch.Generator().manual_seed(3)
    xs = flow.sample(c, g)
    u, _ = flow.to_base(xs, c)
    torch.testing.assert_close(u, torch.randn(5, 3, generator=torch.Generator().manual_seed(3)),
                               rtol=1e-4, atol=1e-4)


def test_gpril_maf_sampling_with_frozen_weights_gives_the_same_numbers_bit_for_bit():
    """Sampling computes each layer's masked weights and context projection once for its D
    passes; a MADE written out plainly, recomputing both at every pass, gives exactly the same
    samples (the speed-up changes no number on the reader's path)."""
    from torch import nn
    torch.manual_seed(1)
    flow = gpril.ConditionalMAF(6, 4, hidden=(16, 16), n_layers=3)
    for p in flow.parameters():
        torch.nn.init.normal_(p, std=0.3)

    def plain(made, x, c):
        h = x
        for i, layer in enumerate(made.layers):
            h = nn.functional.linear(h, layer.weight * getattr(made, f"mask{i}"), layer.bias)
            h = torch.tanh(h + made.context(c) if i == 0 else h)
        out = nn.functional.linear(h, made.out.weight * getattr(made, f"mask{len(made.layers)}"),
                                   made.out.bias)
        mu, alpha = out.chunk(2, -1)
        return mu, 5.0 * torch.tanh(alpha / 5.0)

    c = torch.randn(32, 4)
    with torch.no_grad():
        u = torch.randn(32, 6, generator=torch.Generator().manual_seed(5))
        for made in reversed(flow.mades):
            y, x = u.flip(-1), torch.zeros_like(u)
            for i in range(6):
                mu, alpha = plain(made, x, (c - flow.c_mean) / flow.c_std)
                x[:, i] = mu[:, i] + y[:, i] * torch.exp(alpha[:, i])
            u = x
        want = u * flow.x_std + flow.x_mean
        got = flow.sample(c, torch.Generator().manual_seed(5))
    assert torch.equal(got, want)
    x = torch.randn(8, 6)
    assert all(torch.equal(a, b) for a, b in zip(flow.mades[0](x, c[:8]),
                                                plain(flow.mades[0], x, c[:8])))


def test_gpril_maf_sampling_on_the_fast_path_is_the_readers_to_float32_rounding():
    """The fast path's sampler (NumPy, computing only the two output columns a pass reads)
    draws the same noise and inverts the same layers: its samples are the reader's path's to
    float32 rounding, and the flow maps them back onto that noise."""
    from dc_lesson.nn import fast
    torch.manual_seed(2)
    flow = gpril.ConditionalMAF(6, 4, hidden=(16, 16), n_layers=3)
    for p in flow.parameters():
        torch.nn.init.normal_(p, std=0.3)
    flow.set_standardisation(torch.linspace(-1, 1, 6), torch.linspace(0.5, 2, 6),
                             torch.linspace(1, 2, 4), torch.linspace(0.2, 3, 4))
    c = 2 * torch.randn(256, 4)
    want = flow.sample(c, torch.Generator().manual_seed(5))
    with fast.on():
        got = flow.sample(c, torch.Generator().manual_seed(5))
    assert got.dtype == want.dtype == torch.float32 and got.shape == want.shape
    assert torch.allclose(got, want, rtol=1e-4, atol=1e-4)
    u, _ = flow.to_base(got, c)
    noise = torch.randn(256, 6, generator=torch.Generator().manual_seed(5))
    assert torch.allclose(u, noise, atol=1e-3)
    # a sampler that ignored the context would land elsewhere
    with fast.on():
        other = flow.sample(c + 1, torch.Generator().manual_seed(5))
    assert (other - want).abs().max() > 0.1


def test_gpril_maf_fits_a_conditional_gaussian():
    # x | c ~ N(2c, 0.1^2): the fitted flow's log-density approaches the true one.
    g = torch.Generator().manual_seed(0)
    c = torch.randn(4000, 1, generator=g)
    x = 2 * c + 0.1 * torch.randn(4000, 1, generator=g)
    torch.manual_seed(0)
    flow = gpril.ConditionalMAF(1, 1, hidden=(32, 32), n_layers=2)
    flow.set_standardisation(x.mean(0), x.std(0), c.mean(0), c.std(0))
    opt = torch.optim.Adam(flow.parameters(), lr=3e-3)
    for _ in range(400):
        i = torch.randint(4000, (256,), generator=g)
        loss = -flow.log_prob(x[i], c[i]).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    true = torch.distributions.Normal(2 * c, 0.1).log_prob(x).mean()
    with torch.no_grad():
        fitted = flow.log_prob(x, c).mean()
    assert float(fitted) > float(true) - 0.1


# -- runs: determinism and exact resume ------------------------------------------------------------

@pytest.fixture(scope="module")
def demos1():
    return data.load_demos("reacher1", n_trajectories=3)


def _tiny_ppo(total_steps):
    return ppo.PPOConfig(n_envs=2, n_steps=64, n_epochs=2, n_minibatches=4,
                         total_steps=total_steps)


def _tiny(name, total_steps=512, seed=3):
    if name == "dril":
        return dril.DRILConfig(ppo=_tiny_ppo(total_steps), ensemble_size=3, ensemble_epochs=2,
                               bc_steps=2, bc_batch=64, warm_start_epochs=2, value_warmup=1,
                               seed=seed)
    if name == "pwil":
        return pwil.PWILConfig(ppo=_tiny_ppo(total_steps), value_warmup=1, seed=seed)
    if name == "ndi":
        return ndi.NDIConfig(ppo=_tiny_ppo(total_steps), flow_pairs=200, value_warmup=1,
                             seed=seed).with_flow(iterations=3, hidden=(8, 8))
    return gpril.GPRILConfig(n_envs=2, n_steps=64, total_steps=total_steps, model_steps=2,
                             policy_steps=2, model_batch=32, policy_batch=32,
                             flow_hidden=(8, 8), seed=seed)


MODULES = {"dril": dril, "pwil": pwil, "ndi": ndi, "gpril": gpril}


@pytest.mark.parametrize("name", list(MODULES))
def test_checkpoint_resume_equals_an_uninterrupted_run(name, demos1, tmp_path):
    # 10 iterations of 2 x 64 steps cross the 1000-step episode end, and the stop after
    # iteration 3 falls mid-episode (PWIL's coupling state and GPRIL's buffer must survive).
    mod, cfg = MODULES[name], _tiny(name, total_steps=1280)
    full = mod.train("reacher1", demos1, cfg, progress=False)
    path = tmp_path / f"{name}.ckpt"
    mod.train("reacher1", demos1, cfg, progress=False, checkpoint=path, checkpoint_every=1,
              callback=lambda row, pi: row["update"] == 3)
    resumed = mod.train("reacher1", demos1, cfg, progress=False, checkpoint=path)
    assert len(full.log) == 10
    _same_log(full.log, resumed.log)
    _same_state(full.policy, resumed.policy)
    for key in full.models:
        _same_state(full.models[key], resumed.models[key])
    other = dataclasses.replace(cfg, seed=4)
    with pytest.raises(PolicyFileError, match="seed"):
        mod.train("reacher1", demos1, other, progress=False, checkpoint=path)


def test_gpril_on_the_fast_path_resumes_exactly_and_draws_the_readers_samples(demos1, tmp_path):
    """The fast path draws every policy step's minibatch and noise in the reader's order
    before sampling them in one batch: a checkpointed run resumes to the bit, and its first
    iteration's predecessor likelihood is the reader's to float32 rounding."""
    from dc_lesson.nn import fast
    cfg = _tiny("gpril", total_steps=1280)
    reader = gpril.train("reacher1", demos1, cfg, progress=False)
    path = tmp_path / "gpril.ckpt"
    with fast.on():
        full = gpril.train("reacher1", demos1, cfg, progress=False)
        gpril.train("reacher1", demos1, cfg, progress=False, checkpoint=path,
                    checkpoint_every=1, callback=lambda row, pi: row["update"] == 3)
        resumed = gpril.train("reacher1", demos1, cfg, progress=False, checkpoint=path)
    _same_log(full.log, resumed.log)
    _same_state(full.policy, resumed.policy)
    first, other = full.log[0], reader.log[0]
    for key in ("state_flow_nll", "action_flow_nll", "expert_nll", "predecessor_nll"):
        assert abs(first[key] - other[key]) < 1e-5 * max(1.0, abs(other[key])), key


def test_bad_configurations_are_refused_with_the_field_named():
    with pytest.raises(ValueError, match="ensemble_size"):
        dril.DRILConfig(ensemble_size=1)
    with pytest.raises(ValueError, match="quantile"):
        dril.DRILConfig(quantile=1.5)
    with pytest.raises(ValueError, match="alpha"):
        pwil.PWILConfig(alpha=0)
    with pytest.raises(ValueError, match="subsampling"):
        pwil.PWILConfig(subsampling=0)
    with pytest.raises(ValueError, match="reward"):
        ndi.NDIConfig(reward="log")
    with pytest.raises(ValueError, match="gamma"):
        gpril.GPRILConfig(gamma=1.0)
    with pytest.raises(ValueError, match="value_warmup"):
        pwil.PWILConfig(ppo=_tiny_ppo(512), value_warmup=4)
    with pytest.raises(TypeError, match="PPOConfig"):
        ndi.NDIConfig(ppo={"lr": 1e-3})


# -- each learns: a permutation test against its own start ------------------------------------------

def _start_policy(task, demos):
    """A fresh policy, its normaliser set from the expert's states: the learners' own start
    (its mean action is 0 everywhere)."""
    from dc_lesson import tasks
    from dc_lesson.algorithms import bc
    from dc_lesson.nn.policies import GaussianPolicy
    spec = tasks.spec(task)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        pi = GaussianPolicy(spec.obs_dim, spec.act_dim, (64, 64), log_std_init=-0.5,
                            norm_obs=True)
    pi.update_obs_norm(bc.pairs(demos)[0])
    return pi


def _learning_ppo(total_steps, lr=1e-3, episode_steps=200):
    # PPO's cartpole settings of tests/test_gail.py (gamma 0.98, 8 x 250 steps, 10 epochs of 8
    # minibatches), training episodes cut at 200 steps (many starts to learn from).
    return ppo.PPOConfig(n_envs=8, n_steps=250, n_epochs=10, n_minibatches=8, lr=lr,
                         gamma=0.98, total_steps=total_steps, episode_steps=episode_steps)


def _gain_test(name, task, config, min_gain, n_demos=4):
    """Trains ``name`` from :func:`_start_policy`; evaluates the start and the result on the
    same 10 fresh episodes (mean action); a one-sided permutation test of the mean return."""
    import copy
    import time
    from scipy import stats
    from dc_lesson.data import rollout
    demos = data.load_demos(task, n_trajectories=n_demos)
    start_pi = _start_policy(task, demos)
    t0 = time.perf_counter()
    result = MODULES[name].train(task, demos, config, policy=copy.deepcopy(start_pi),
                                 progress=False)
    seconds = time.perf_counter() - t0
    learned = rollout.returns(rollout.collect(task, result.policy, 10, seed=2024,
                                              progress=False))
    start = rollout.returns(rollout.collect(task, start_pi, 10, seed=2024, progress=False))
    test = stats.permutation_test((learned, start),
                                  lambda x, y, axis: x.mean(axis) - y.mean(axis),
                                  permutation_type="independent", alternative="greater",
                                  n_resamples=9999, vectorized=True, rng=0)
    gain = learned.mean() - start.mean()
    print(f"\n{name.upper()} {task}: {seconds:.0f} s; learned {learned.mean():.0f} ± "
          f"{learned.std():.0f}, start {start.mean():.0f} ± {start.std():.0f}; gain {gain:.0f};"
          f" p = {test.pvalue:.4f}")
    assert test.pvalue < 0.05
    assert gain >= min_gain
    return result


# DRIL on cartpole from a fresh policy (mean action 0: return about 620 on these episodes), 30k
# interactions, 16 BC steps per iteration: measured 1000 ± 0 against 618 ± 46, in 44 s.
DRIL_LEARN = dril.DRILConfig(ppo=_learning_ppo(30_000), ensemble_epochs=20, bc_steps=16,
                             value_warmup=0, seed=0)


def test_dril_improves_on_its_start_on_cartpole():
    _gain_test("dril", "cartpole", DRIL_LEARN, min_gain=250)


# NDI on reacher1 from a fresh policy (it stays still: return 0), 40k interactions with the
# module's defaults: measured 940 ± 31 against 0 ± 0, 117 s on a machine at load 6 (two cores).
NDI_LEARN = ndi.NDIConfig(ppo=_learning_ppo(40_000), value_warmup=0, seed=0)


def test_ndi_improves_on_its_start_on_reacher1():
    _gain_test("ndi", "reacher1", NDI_LEARN, min_gain=300)


# GPRIL's two halves.  Without the predecessor term (w = 0) the loop is BC on the expert's pairs,
# and it learns cartpole from a fresh policy: measured 1000 ± 0 against 618 ± 46 in 18 s (20k
# interactions).  With the paper's predecessor term (w = 1) the same run ended at 425 ± 15, below
# its start (predecessors sampled from flows of a poor learner's experience carry that learner's
# own actions); 30k interactions from an unnormalised start gave 261 against 646.  That is marked
# as an expected failure, the DC paper's "no meaningful results", not hidden.
GPRIL_LEARN = gpril.GPRILConfig(total_steps=20_000, episode_steps=200, seed=0)


def test_gpril_without_predecessors_is_bc_and_learns_cartpole():
    _gain_test("gpril", "cartpole", dataclasses.replace(GPRIL_LEARN, predecessor_weight=0.0),
               min_gain=250)


@pytest.mark.xfail(reason="GPRIL with its predecessor term (w = 1) fell below its start on "
                          "cartpole (measured 425 against 618); see the comment above",
                   strict=False)
def test_gpril_improves_on_its_start_on_cartpole():
    _gain_test("gpril", "cartpole", GPRIL_LEARN, min_gain=250)


# PWIL did not learn on the cheap tasks within the budget, and the test says so.  Its kernel
# exp(-5 T c / sqrt(d)) is a few expert standard deviations wide, and the expert's states on
# these tasks barely vary (a reacher at its target, a balanced cartpole): every pair of a fresh
# policy, and most of a noisy PPO learner's, lie hundreds of standard deviations away, where the
# reward is 0 to float precision.  Measured: reacher1 from a fresh policy 0 ± 2 against 0 ± 0
# (40k interactions, mean reward 0.000); from the BC warm start 582 ± 475 against 578 ± 472
# (std_floor 0.1: 585); cartpole from a fresh unnormalised policy 334 ± 72 against 646 (60k).
PWIL_LEARN = pwil.PWILConfig(ppo=_learning_ppo(40_000), value_warmup=0, seed=0)


@pytest.mark.xfail(reason="PWIL's reward is 0 almost everywhere on reacher1 and cartpole; see "
                          "the measured runs above", strict=False)
def test_pwil_improves_on_its_start_on_reacher1():
    _gain_test("pwil", "reacher1", PWIL_LEARN, min_gain=300)


def test_learner_cost_benchmark_reports_setup_and_loop():
    from dc_lesson.perf import cost
    out = cost.learner_costs("reacher1", ["pwil"], 2048, "smoke", warm_start_epochs=1)
    row, = out["rows"]
    assert row["learner"] == "pwil" and row["env_steps"] == 2048
    assert 0 < row["loop_seconds"] <= row["seconds"] + 1e-9
    assert row["seconds_per_100k"] == pytest.approx(
        row["setup_seconds"] + row["loop_seconds"] / 2048 * 1e5)


def test_the_cost_benchmark_runs_a_cut_too_short_for_gails_warm_up():
    """``python -m dc_lesson.perf.cost --steps 8192`` once died at GAIL's check that its critic
    warm-up leaves iterations to train the policy: a cut that short now runs the fewest whole
    iterations each learner accepts (and the row reports the interactions that ran)."""
    from dc_lesson import budget
    from dc_lesson.perf import cost
    b = budget.get("lesson")
    for name in cost.LEARNERS:
        cfg = cost._config(name, b, 8192)
        if hasattr(cfg, "value_warmup"):
            assert cfg.ppo.n_updates > cfg.value_warmup
