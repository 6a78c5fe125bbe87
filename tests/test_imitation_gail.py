"""imitation's GAIL beside ours: the weight map, the training environment, the settings and
their recorded changes; with imitation installed, the SB3 start and a tiny run."""

import copy
import importlib.util

import numpy as np
import pytest
import torch

from dc_lesson import tasks
from dc_lesson.algorithms import base
from dc_lesson.nn.policies import GaussianPolicy
from dc_lesson.perf import imitation_gail as ig

HAS_IMITATION = importlib.util.find_spec("imitation") is not None
needs_imitation = pytest.mark.skipif(not HAS_IMITATION, reason="imitation 1.0.1 is not "
                                     "installed here (it lives in its own venv: see "
                                     "dc_lesson.perf.imitation_ref)")


def _start(obs_dim=11, act_dim=3, seed=0):
    torch.manual_seed(seed)
    policy = GaussianPolicy(obs_dim, act_dim, (64, 64), norm_obs=True)
    with torch.no_grad():   # a fitted-looking start: non-trivial weights and normaliser
        for p in policy.mean_net.parameters():
            p.add_(0.1 * torch.randn_like(p))
        policy.obs_norm.update(torch.randn(500, obs_dim) * 3 + 1)
    base.set_start_noise(policy, base.START_LOG_STD)
    return policy


def test_the_weights_go_to_sb3s_names_and_back_unchanged():
    start = _start()
    state = ig.sb3_state(start)
    assert set(state) == set(ig.LAYERS.values())   # mean net and log-std, no value net
    # SB3 trains them: change them as training would, and read them back into ours
    trained = {k: v + 0.01 for k, v in state.items()}
    policy = ig.from_sb3(trained, start)
    ours = policy.state_dict()
    for name, theirs in ig.LAYERS.items():
        assert torch.equal(ours[name], trained[theirs])
    for name in ig.NORM:   # the normaliser is the start's, frozen
        assert torch.equal(ours[name], start.state_dict()[name])
    assert policy.config() == start.config() and policy is not start
    # the round trip of an untrained policy is the start itself, action for action
    back = ig.from_sb3(state, start)
    obs = torch.randn(7, 11)
    assert torch.equal(back(obs), start(obs))


def test_reading_the_weights_back_draws_no_random_numbers():
    # a checkpoint evaluation mid-run must not move the generator SB3 samples actions from
    start, state = _start(), None
    state = ig.sb3_state(start)
    torch.manual_seed(5)
    ig.from_sb3(state, start)
    after = torch.rand(3)
    torch.manual_seed(5)
    assert torch.equal(after, torch.rand(3))


def test_the_layer_map_needs_a_two_layer_gaussian():
    with pytest.raises(ValueError, match="two hidden layers"):
        ig.from_sb3({}, GaussianPolicy(4, 1, (32,)))


def test_the_hopper_ends_a_training_episode_where_our_learners_do():
    env = ig.TrainingEnv("hopper", "hopper-fall")
    obs, _ = env.reset(seed=0)
    fell = tasks.TERMINATIONS["hopper-fall"]
    terminated = False
    for _ in range(300):   # with no torque the hopper falls within a few dozen steps
        obs, reward, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        assert terminated == bool(fell(obs[None])[0]) and not truncated
        if terminated:
            break
    assert terminated


def test_without_a_termination_an_episode_only_ends_at_the_horizon():
    env = ig.TrainingEnv("halfcheetah", None)
    env.reset(seed=0)
    horizon = tasks.spec("halfcheetah").horizon
    ends = []
    for t in range(horizon):
        _, _, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        assert not terminated
        ends.append(truncated)
    assert ends[-1] and not any(ends[:-1])


def test_the_settings_are_imitations_tuned_ones_with_each_change_named():
    used, dev = ig.settings("hopper", steps=1_000_000, n_demos=4, n_expert_pairs=4000,
                            terminate="hopper-fall")
    rec = ig.RECOMMENDED["hopper"]
    assert used["ppo"] == rec["ppo"] and used["demo_batch_size"] == 128
    assert used["rl_batch_size"] // used["num_vec"] == 512   # SB3's n_steps, as imitation sets
    assert used["policy"]["pi"] == [64, 64] and used["allow_variable_horizon"]
    changed = {d["setting"] for d in dev}
    assert {"total_timesteps", "start", "activation", "allow_variable_horizon",
            "observation normaliser of the policy"} <= changed
    assert "demo_batch_size" not in changed and "policy network" not in changed
    assert all(d["why"] for d in dev)

    used, dev = ig.settings("halfcheetah", steps=2_000_000, n_demos=4, n_expert_pairs=4000)
    changed = {d["setting"]: d for d in dev}
    # imitation's 8192 expert pairs per step: more than 4 demonstrations hold
    assert used["demo_batch_size"] == 4000 and changed["demo_batch_size"]["recommended"] == 8192
    # its FeedForward32Policy: our 64-64 policy for the start, its 32-32 value network kept
    assert used["policy"] == {**used["policy"], "pi": [64, 64], "vf": [32, 32]}
    assert "policy network" in changed and "activation" not in changed
    assert not used["allow_variable_horizon"] and "allow_variable_horizon" not in changed
    with pytest.raises(ValueError, match="tunes GAIL"):
        ig.settings("reacher4", steps=1, n_demos=1, n_expert_pairs=1)


def test_the_studys_facts_restated_in_perf_are_still_the_studys():
    # perf does not import experiments (tests/test_layers.py): the module restates them
    from dc_lesson.experiments import protocol
    from dc_lesson.experiments.studies import competence
    assert ig.N_DEMOS == competence.N_DEMOS and ig.KEEP_TASKS == competence.KEEP_TASKS
    assert ig.TERMINATE == competence.TERMINATE
    assert ig.STUDY_EVAL_SEED == protocol.expert_eval_seed(0)
    assert ig.OUR_GAIL_FIXES == competence.FIXES["gail"]
    assert ig.default_part("hopper") == "keep" and ig.default_part("halfcheetah") == "learn"
    # and the study's GAIL trains the hopper with that termination
    from dc_lesson import budget
    cfg = competence.learner_config("gail", budget.get("smoke"), "keep", 0, "hopper")
    assert cfg.ppo.terminate == ig.TERMINATE["hopper"] and cfg.start_log_std == base.START_LOG_STD


def test_ours_is_read_from_the_studys_result_at_the_same_budget_and_length(monkeypatch):
    from dc_lesson import budget
    b = budget.get("lesson")
    obs = [{"row": r, "task": "hopper", "seed": s, "part": "keep", "start": 1.0 + s,
            "final": 0.5, "curve": [0.9], "curve_steps": [50_000], "train_seconds": 100.0}
           for r in ("dc", "gail") for s in (0, 1)]
    stored = {"budget": "lesson", "steps": {"keep": b.competence_keep_steps}, "observations": obs}
    monkeypatch.setattr(ig, "read_result", lambda name: stored)
    ours = ig._ours("hopper", "keep", 1, b, b.competence_keep_steps)
    assert ours["stored_start"] == {"learner": "dc", "scaled_return": 2.0}
    assert ours["gail"]["final"] == 0.5 and ours["gail"]["train_seconds"] == 100.0
    short = ig._ours("hopper", "keep", 1, b, 20_000)   # another length: the same start
    assert short["gail"] is None and short["stored_start"]["scaled_return"] == 2.0
    assert ig._ours("hopper", "keep", 1, budget.get("smoke"), 2048)["stored_start"] is None
    assert ig._ours("halfcheetah", "learn", 1, b, b.competence_keep_steps)["gail"] is None


@pytest.mark.skipif(HAS_IMITATION, reason="imitation is installed here")
def test_without_imitation_it_says_how_to_install_it_and_computes_nothing(tmp_path, capsys):
    out = tmp_path / "gail.json"
    with pytest.raises(SystemExit) as e:
        ig.main(["--steps", "4096", "--out", str(out)])
    assert e.value.code == 2 and not out.exists()
    assert "imitation 1.0.1" in capsys.readouterr().err


@needs_imitation
def test_sb3s_policy_starts_as_our_start():
    start = _start()
    env = ig._imitation()["DummyVecEnv"]([lambda: ig.TrainingEnv("hopper", "hopper-fall")])
    used, _ = ig.settings("hopper", steps=4096, n_demos=4, n_expert_pairs=4000)
    gen = ig.make_generator(env, start, 0, used)
    obs = torch.randn(16, 11) * 3 + 1
    with torch.no_grad():
        dist = gen.policy.get_distribution(obs)
        mean = dist.distribution.mean
        assert torch.allclose(mean, start(obs), atol=1e-6)
        assert torch.equal(gen.policy.log_std, start.log_std)
    theirs, ours = gen.policy.state_dict(), start.state_dict()
    assert all(torch.equal(theirs[t], ours[o]) for o, t in ig.NORM.items())
    # imitation's value network: fresh (SB3's init), tanh as the policy's
    assert [m.out_features for m in gen.policy.mlp_extractor.value_net
            if isinstance(m, torch.nn.Linear)] == [64, 64]


@needs_imitation
def test_a_tiny_run_from_a_bc_start_ends_as_our_policy(tmp_path):
    from dc_lesson.data import store
    demos = store.load_demos("hopper", n_trajectories=2)
    start = ig._bc.warm_start_policy(demos, 0, max_epochs=1)
    base.set_start_noise(start, base.START_LOG_STD)
    kept = copy.deepcopy(start)
    torch.set_num_threads(1)
    policy, info = ig.imitation_gail("hopper", demos, start, 0, 4096, terminate="hopper-fall")
    assert isinstance(policy, GaussianPolicy) and info["interactions"] == 4096
    assert info["train_seconds"] > 0 and info["settings"]["total_timesteps"] == 4096
    # trained, from the start: the mean net moved, the normaliser did not
    assert not torch.equal(policy.mean_net[0].weight, kept.mean_net[0].weight)
    assert torch.equal(policy.obs_norm.mean, kept.obs_norm.mean)
    from dc_lesson.evaluation import evaluate_policy
    ev = evaluate_policy("hopper", policy, None, n_episodes=1, divergences=False)
    assert np.isfinite(ev["scaled_return"])


def test_added_rows_join_a_stored_file_only_under_the_same_settings():
    old = {"command": "a", "seeds": [0, 1], "revision": "r1", "time": "t", "task": "hopper",
           "part": "learn", "steps": 10, "rows": [{"seed": 0, "final": 0.1},
                                                   {"seed": 1, "final": 0.2}]}
    new = {"revision": "r2", "task": "hopper", "part": "learn", "steps": 10,
           "rows": [{"seed": 1, "final": 0.3}, {"seed": 3, "final": 0.4}]}
    got = ig.merged(old, new, "b")
    assert [(r["seed"], r["final"]) for r in got["rows"]] == [(0, 0.1), (1, 0.3), (3, 0.4)]
    assert got["seeds"] == [0, 1, 3] and got["command"] == "a ; then b"
    assert got["revisions"] == ["r1", "r2"]
    third = ig.merged(got, {**new, "revision": "r3", "rows": [{"seed": 4, "final": 0.5}]}, "c")
    assert third["seeds"] == [0, 1, 3, 4] and third["revisions"] == ["r1", "r2", "r3"]
    with pytest.raises(ValueError, match="'steps' is 20 here and 10"):
        ig.merged(old, {**new, "steps": 20}, "b")
    # a file merged by hand keeps its revisions per seed set: read as their values
    by_hand = {**old, "revisions": {"[1]": "r0", "[0]": "r1"}}
    assert ig.merged(by_hand, new, "b")["revisions"] == ["r0", "r1", "r2"]


def test_rows_that_cannot_be_added_are_kept_beside_the_file(tmp_path, monkeypatch, capsys):
    import json
    out = tmp_path / "r.json"
    out.write_text(json.dumps({"task": "hopper", "part": "learn", "steps": 10, "rows": [],
                               "command": "a"}))
    monkeypatch.setattr(ig, "ready", lambda *a, **k: None)
    monkeypatch.setattr(ig, "run", lambda *a, **k: {"task": "hopper", "part": "learn",
                                                     "steps": 20, "rows": []})
    with pytest.raises(SystemExit):
        ig.main(["--task", "hopper", "--part", "learn", "--seeds", "3", "--out", str(out),
                 "--add"])
    side = ig.side_path(out, [3])
    assert "'steps' is 20 here and 10" in capsys.readouterr().err
    assert side.exists() and json.loads(side.read_text())["steps"] == 20


def test_add_refuses_another_part_before_any_compute(tmp_path, monkeypatch, capsys):
    import json
    out = tmp_path / "r.json"
    out.write_text(json.dumps({"task": "hopper", "part": "learn", "rows": []}))
    monkeypatch.setattr(ig, "ready", lambda *a, **k: None)
    monkeypatch.setattr(ig, "run", lambda *a, **k: pytest.fail("computed before refusing"))
    with pytest.raises(SystemExit):
        ig.main(["--task", "hopper", "--part", "keep", "--out", str(out), "--add"])
    assert "part is 'keep' here and 'learn'" in capsys.readouterr().err
