"""Distributional Cloning: the update's algebra, the switches, determinism and resume."""

import copy
import dataclasses
import json

import numpy as np
import pytest
import torch

from dc_lesson import budget
from dc_lesson.algorithms import bc, dc, ppo
from dc_lesson.nn import fast
from dc_lesson.nn.policies import PolicyFileError

TASK = "reacher1"
TINY = dc.DCConfig(loops=2, iterations=2, flow_states=200, flow_refit_iterations=3,
                   bc_steps=2, bc_batch_size=32, seed=3).with_ppo(
    n_envs=2, n_steps=40, n_epochs=2, n_minibatches=4).with_flow(iterations=4, hidden=(16, 16))


def _three(r):
    """(policy, flow, log) of a TrainResult."""
    return r.policy, r.models["flow"], r.log



@pytest.fixture(scope="module")
def start():
    torch.set_num_threads(1)
    policy, demos, _ = bc.warm_start(TASK, 3, seed=0, max_epochs=3)
    return policy, demos


def _fixture_learner(start, config):
    policy, demos = start
    policy = copy.deepcopy(policy)
    learner = dc.make_learner(policy, config, policy.obs_dim)
    envs = ppo.EnvBatch(TASK, config.n_envs, seed=5)
    gen = torch.Generator().manual_seed(11)
    dc.copy_into(learner.pi_prime, learner.pi)
    batch = ppo.collect_batch(envs, learner.pi_prime, learner.value_fn, config.n_steps, gen)
    rewards = torch.rand(batch.env_rewards.shape, generator=gen)
    obs, act = dc.expert_pairs(demos)
    return learner, batch, rewards, obs, act, gen


def test_averaging_is_the_exact_elementwise_mean_and_leaves_the_normaliser_alone(start):
    a, b = copy.deepcopy(start[0]), copy.deepcopy(start[0])
    with torch.no_grad():
        for p in b.parameters():
            p.add_(torch.randn_like(p))
        b.obs_norm.mean.add_(5.0)       # a different normaliser must not leak into a
    pa, pb = [p.clone() for p in a.parameters()], [p.clone() for p in b.parameters()]
    norm_before = a.obs_norm.mean.clone()
    dc.average_into(a, b, average_log_std=True)
    for p, x, y in zip(a.parameters(), pa, pb):
        assert torch.equal(p, (x + y) * 0.5)
    assert torch.equal(a.obs_norm.mean, norm_before)

    c = copy.deepcopy(start[0])
    pc = dc.flat(dc.policy_parameters(c, False)).clone()
    dc.average_into(c, b, average_log_std=False)
    assert torch.equal(c.log_std, b.log_std)                          # z takes pi''s log-std
    assert torch.allclose(dc.flat(dc.policy_parameters(c, False)),
                          (pc + dc.flat(dc.policy_parameters(b, False))) / 2)


def test_with_ppo_off_an_iteration_is_a_bc_step_at_half_the_learning_rate(start):
    config = dataclasses.replace(TINY, ppo_step=False, bc_steps=1)
    learner, batch, rewards, obs, act, gen = _fixture_learner(start, config)
    ref = copy.deepcopy(learner.pi)
    ref_opt = fast.adamw(ref.parameters(), lr=config.lr / 2, eps=1e-5,
                                weight_decay=config.weight_decay)
    ref_gen = torch.Generator()
    ref_gen.set_state(gen.get_state())
    o, a = dc.sample_bc_pairs(obs, act, batch, config, ref_gen)
    bc.bc_step(ref, ref_opt, o, a, config.max_grad_norm)

    dc.parameter_averaging(learner, batch, rewards, obs, act, config, gen)
    moved = (dc.flat(ref.parameters()) - dc.flat(start[0].parameters())).abs().max()
    assert moved > 1e-5   # the step did something
    assert torch.allclose(dc.flat(learner.pi.parameters()), dc.flat(ref.parameters()),
                          atol=1e-6, rtol=0)


def test_with_bc_off_an_iteration_is_a_ppo_step_averaged_with_its_start(start):
    config = dataclasses.replace(TINY, bc_step=False)
    learner, batch, rewards, obs, act, gen = _fixture_learner(start, config)
    start_params = dc.flat(learner.pi.parameters()).clone()
    ref_pi, ref_v = copy.deepcopy(learner.pi_prime), copy.deepcopy(learner.value_fn)
    ref_opt = fast.adamw([{"params": list(ref_pi.parameters()),
                                  "weight_decay": config.weight_decay},
                                 {"params": list(ref_v.parameters()), "weight_decay": 0.0}],
                                lr=config.lr, eps=1e-5)
    ref_batch = copy.deepcopy(batch)
    ref_batch.advantages, ref_batch.returns = ppo.compute_gae(
        rewards, batch.values, batch.next_values, batch.dones, config.ppo.gamma, config.ppo.gae_lambda)
    ref_gen = torch.Generator()
    ref_gen.set_state(gen.get_state())
    ppo.ppo_update(ref_pi, ref_v, ref_opt, ref_batch, config.ppo_config, ref_gen)

    dc.parameter_averaging(learner, batch, rewards, obs, act, config, gen)
    expected = (start_params + dc.flat(ref_pi.parameters())) / 2
    assert not torch.allclose(expected, start_params, atol=1e-5)
    assert torch.allclose(dc.flat(learner.pi.parameters()), expected, atol=1e-6, rtol=0)
    assert torch.equal(dc.flat(learner.pi_prime.parameters()), dc.flat(ref_pi.parameters()))


def test_ppo_old_log_probabilities_are_those_of_pi_at_the_iteration_start(start):
    learner, batch, *_ = _fixture_learner(start, TINY)
    obs = batch.obs.reshape(-1, batch.obs.shape[-1])
    act = batch.actions.reshape(-1, batch.actions.shape[-1])
    with torch.no_grad():
        assert torch.allclose(batch.logprobs.reshape(-1), learner.pi.log_prob(obs, act),
                              atol=1e-5)


def test_consensus_admm_keeps_the_duals_balanced_and_logs_residuals(start):
    config = dataclasses.replace(TINY, update="admm", rho=0.5)
    learner, batch, rewards, obs, act, gen = _fixture_learner(start, config)
    row = dc.consensus_admm(learner, batch, rewards, obs, act, config, gen)
    u1, u2 = learner.duals
    # z = mean(x_i + u_i) and u_i += x_i - z make the scaled duals sum to zero.
    assert torch.allclose(u1 + u2, torch.zeros_like(u1), atol=1e-6)
    assert u1.abs().max() > 0
    assert row["primal_residual"] > 0 and row["dual_residual"] > 0
    # z is the average of the two copies plus their (old, zero) duals after one iteration.
    x1 = dc.flat(dc.policy_parameters(learner.pi_bc))
    x2 = dc.flat(dc.policy_parameters(learner.pi_prime))
    assert torch.allclose(dc.flat(dc.policy_parameters(learner.pi)), (x1 + x2) / 2, atol=1e-6)
    averaging = dc.make_learner(copy.deepcopy(start[0]), TINY, start[0].obs_dim)
    with pytest.raises(ValueError, match="update='admm'"):   # no duals, no x_1
        dc.consensus_admm(averaging, batch, rewards, obs, act, TINY, gen)


def _params(policy):
    return dc.flat(policy.parameters())


def test_same_seed_same_run_and_another_seed_differs(start):
    runs = [_three(dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False))
            for cfg in (TINY, TINY, dataclasses.replace(TINY, seed=4))]
    assert torch.equal(_params(runs[0][0]), _params(runs[1][0]))
    strip = lambda log: [{k: v for k, v in r.items() if "second" not in k} for r in log]
    assert strip(runs[0][2]) == strip(runs[1][2])
    assert not torch.equal(_params(runs[0][0]), _params(runs[2][0]))
    kinds = [r["kind"] for r in runs[0][2]]
    assert kinds == ["flow", "iteration", "iteration", "flow", "iteration", "iteration"]
    assert runs[0][2][-1]["env_steps"] == TINY.env_steps(TASK)


def test_a_run_interrupted_after_a_loop_resumes_identical(start, tmp_path):
    ckpt = tmp_path / "dc.ckpt"
    full, _, full_log = _three(dc.train(TASK, start[1], TINY, policy=copy.deepcopy(start[0]), progress=False))
    part, _, part_log = _three(dc.train(TASK, start[1], TINY, policy=copy.deepcopy(start[0]), progress=False,
                                 checkpoint=ckpt, stop_after_loop=0))
    assert ckpt.exists() and len(part_log) == 3            # loop 0 only: flow + 2 iterations
    resumed, _, log = _three(dc.train(TASK, start[1], TINY, policy=copy.deepcopy(start[0]), progress=False,
                               checkpoint=ckpt))
    assert torch.equal(_params(resumed), _params(full))
    assert [r["env_steps"] for r in log] == [r["env_steps"] for r in full_log]

    with pytest.raises(PolicyFileError, match="another configuration"):
        dc.train(TASK, start[1], dataclasses.replace(TINY, lr=1e-3), policy=copy.deepcopy(start[0]),
                 progress=False, checkpoint=ckpt)
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(PolicyFileError, match="bad.ckpt"):
        dc.train(TASK, start[1], TINY, policy=copy.deepcopy(start[0]), progress=False, checkpoint=bad)


def test_a_run_stopped_mid_loop_resumes_identical(start, tmp_path):
    """Under ADMM (duals and the BC copy in the file) a run stopped by its callback in loop 1's
    last iteration resumes from the checkpoint after that loop's first one: same parameters,
    same log."""
    cfg = dataclasses.replace(TINY, update="admm")
    full = dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False)
    ckpt = tmp_path / "dc_admm.ckpt"
    rows = []
    part = dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False,
                    checkpoint=ckpt, checkpoint_every=1,
                    callback=lambda row, pi: rows.append(row) or len(rows) == 4)
    assert [(r["loop"], r["iteration"]) for r in rows] == [(0, 1), (0, 2), (1, 1), (1, 2)]
    assert len(part.log) == len(full.log)             # the last iteration ran, unsaved
    resumed = dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False,
                       checkpoint=ckpt)
    assert torch.equal(_params(resumed.policy), _params(full.policy))
    as_text = lambda log: [json.dumps({k: v for k, v in r.items() if "second" not in k})
                           for r in log]   # as text: the file's NaNs are new objects
    assert as_text(resumed.log) == as_text(full.log)


def test_a_checkpoint_of_dcs_old_layout_is_refused_with_the_fix(start, tmp_path):
    """DC's own checkpoint layout (version 1) gave way to base.save_run's (version 2); a file of
    the old layout is refused, naming the file and what to do, not half-loaded."""
    from dc_lesson.nn.policies import atomic_torch_save
    old = tmp_path / "old_dc.ckpt"
    atomic_torch_save({"format": dc.CHECKPOINT_FORMAT, "version": 1, "task": TASK,
                       "config": TINY.to_json(), "loop": 1, "iteration": 0, "learner": {},
                       "log": "[]"}, old)
    with pytest.raises(PolicyFileError, match=r"old_dc\.ckpt has version 1.*delete .*old_dc"):
        dc.train(TASK, start[1], TINY, policy=copy.deepcopy(start[0]), progress=False,
                 checkpoint=old)


def test_reward_scale_maps_the_expert_median_to_one_and_far_states_to_zero():
    logp = np.linspace(-10, 10, 1001)
    scale = dc.RewardScale.from_expert(logp)
    r = scale(torch.tensor([100.0, 0.0, -1e4]))
    assert r[0] == 1 and r[2] == 0 and 0.4 < r[1] <= 1
    assert scale.high == pytest.approx(0.0, abs=0.05)


def test_bad_configurations_and_inputs_say_what_is_wrong(start):
    with pytest.raises(ValueError, match="update must be one of"):
        dc.DCConfig(update="sgd")
    with pytest.raises(ValueError, match="reward must be one of"):
        dc.DCConfig(reward="log")
    with pytest.raises(ValueError, match="n_minibatches"):
        dc.DCConfig().with_ppo(n_envs=3, n_steps=5, n_minibatches=4)
    with pytest.raises(TypeError, match="PPOConfig"):
        dc.DCConfig(ppo={"n_envs": 2})
    with pytest.raises(ValueError, match="demonstrations are of 'reacher1'"):
        dc.train("reacher2", start[1], TINY, policy=copy.deepcopy(start[0]), progress=False)


def test_dc_beats_the_random_policy_on_reacher1():
    """Statistical: DC (from a BC start on 3 demonstrations, 24 iterations of 1,000 steps)
    against the random policy on the same 10 fresh episodes; one-sided exact permutation
    test p < 0.01 and a gain of at least 0.3 in scaled return.  A broken update (a sign error,
    averaging the wrong tensors, a reward that pushes away from the expert's states) ends
    near or below random."""
    from dc_lesson import evaluation
    from dc_lesson.evaluation import metrics
    from dc_lesson.data import rollout
    from test_ppo import permutation_p_value
    torch.set_num_threads(1)
    policy, demos, _ = bc.warm_start(TASK, 3, seed=1, max_epochs=30)
    config = dc.DCConfig(loops=2, iterations=12, flow_states=2000, flow_refit_iterations=30,
                         seed=1).with_ppo(n_envs=4, n_steps=250).with_flow(iterations=100)
    pi, _, log = _three(dc.train(TASK, demos, config, policy=policy, progress=False))
    learned = evaluation.evaluate_policy(TASK, pi, demos, n_episodes=10)
    rand = rollout.collect(TASK, rollout.RandomPolicy(TASK, 0), 10, seed=evaluation.EVAL_SEED,
                           progress=False)
    _, random_scaled = metrics.scaled_return(TASK, rand)
    _, dc_scaled = metrics.scaled_return(TASK, learned["returns"])
    p = permutation_p_value(dc_scaled, random_scaled)
    print(f"DC scaled return {dc_scaled.mean():.2f}, random {random_scaled.mean():.2f}, "
          f"p = {p:.2g}")
    assert p < 0.01 and dc_scaled.mean() - random_scaled.mean() >= 0.3
    assert all(np.isfinite(r["bc_nll"]) for r in log if r["kind"] == "iteration")


def test_the_gail_reward_arm_trains_a_state_discriminator_and_resumes_identical(start, tmp_path):
    """reward="gail" (Algorithm 2 with GAIL's -log(1 - D(s')) in place of log P_w): no flow is
    fitted, the discriminator learns (its expert accuracy is logged), and an interrupted run
    resumes to the same parameters as an uninterrupted one."""
    cfg = dataclasses.replace(TINY, reward="gail")
    full = dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False)
    assert full.models["flow"] is None
    assert [r["kind"] for r in full.log] == ["iteration"] * 4
    assert all(0.0 <= r["disc_acc_expert"] <= 1.0 and r["reward_mean"] > 0 for r in full.log)
    assert full.log[-1]["env_steps"] == cfg.env_steps(TASK) == 4 * cfg.batch_size
    ckpt = tmp_path / "dc_gail.ckpt"
    dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False,
             checkpoint=ckpt, stop_after_loop=0)
    resumed = dc.train(TASK, start[1], cfg, policy=copy.deepcopy(start[0]), progress=False,
                       checkpoint=ckpt)
    assert torch.equal(_params(resumed.policy), _params(full.policy))
    assert not torch.equal(_params(full.policy), _params(
        dc.train(TASK, start[1], TINY, policy=copy.deepcopy(start[0]), progress=False).policy))


def test_the_preset_spends_the_budgets_interactions():
    from dc_lesson import budget
    for name in ("smoke", "lesson", "paper"):
        b = budget.get(name)
        c = dc.preset(b)
        spent = c.loops * c.iterations * c.batch_size
        assert b.il_steps - c.loops * c.batch_size < spent <= b.il_steps, name
    assert dc.preset(budget.get("lesson"), loops=4).iterations * 4 * \
        dc.DCConfig().batch_size <= budget.get("lesson").il_steps


def test_the_flows_numerics_are_settings_that_reach_the_fit_and_the_reward():
    """P_w's step sizes, nodes and tanh are settings of ``DCConfig.flow`` that reach the fit
    and are in the JSON under the flat names every stored cell was listed with
    (``dc.FLOW_STORED_NAMES``): the stored runs' numerics (0.25, 0.25, 4, torch) hash
    differently from today's defaults (0.5, 0.5, 3, numpy), so no cell of the one is taken for
    the other."""
    import json as _json
    from dc_lesson.experiments.studies import table3 as _t3
    today = _t3.learner_config("dc", budget.get("lesson"), "hopper", 0)
    got = _json.loads(today.to_json())
    assert {k: got[k] for k in ("flow_step", "reward_step", "reward_nodes", "flow_tanh")} == {
        "flow_step": 0.5, "reward_step": 0.5, "reward_nodes": 3, "flow_tanh": "numpy"}
    flow = today.flow
    assert (flow.step_size, flow.eval_step_size, flow.eval_quadrature, flow.tanh) == (
        0.5, 0.5, 3, "numpy")
    stored = today.with_flow(**dc.STORED_NUMERICS)
    stored_names = {v: k for k, v in dc.FLOW_STORED_NAMES.items()}
    assert {k: _json.loads(stored.to_json())[stored_names[k]] for k in dc.STORED_NUMERICS} \
        == dc.STORED_NUMERICS and stored.to_json() != today.to_json()
    for name in dc.STORED_NUMERICS:
        with pytest.raises(ValueError, match=name):
            today.with_flow(**{name: "fast" if name == "tanh" else 0})


def test_flow_settings_nest_and_store_in_the_flat_form():
    """``DCConfig.flow`` is SoftFlow's config: a default one stores exactly the flat names of
    the cells listed before the nesting, any other flow setting joins the JSON under "flow" (a
    new cell, never a reused one), and a seed of its own is refused (DC's seed decides)."""
    import json as _json
    cfg = dc.DCConfig()
    d = _json.loads(cfg.to_json())
    assert "flow" not in d and set(dc.FLOW_STORED_NAMES) <= set(d)
    assert d["flow_iterations"] == cfg.flow.iterations == 300
    changed = _json.loads(cfg.with_flow(batch_size=128).to_json())
    assert changed["flow"] == {"batch_size": 128}
    with pytest.raises(ValueError, match="flow.seed"):
        cfg.with_flow(seed=4)
    with pytest.raises(TypeError, match="SoftFlowConfig"):
        dataclasses.replace(cfg, flow={"iterations": 3})


def test_ppo_settings_dc_sets_itself_are_refused_not_ignored():
    """DC's one rate and clip reach both copies; a ``ppo`` that sets them otherwise (or
    anneals) is refused with the field to set, never silently overridden."""
    cfg = dc.DCConfig()
    for name, value in (("lr", 1e-3), ("max_grad_norm", 1.0), ("anneal_lr", True)):
        with pytest.raises(ValueError, match=f"ppo.{name}"):
            cfg.with_ppo(**{name: value})
    assert dc.DCConfig(lr=1e-4).ppo_config.lr == 1e-4
    assert dc.DCConfig(lr=1e-4).with_ppo(lr=1e-4).ppo_config.lr == 1e-4
