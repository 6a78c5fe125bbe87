"""The predictive-sampling planner: exact reward prediction, determinism, that it plans at
all (against random actions), its settings file, and resumable demonstration runs."""

import json

import numpy as np
import pytest

from dc_lesson.experts import demos
from dc_lesson.data import rollout
from dc_lesson import tasks
from dc_lesson.experts import load_expert, planner
from dc_lesson.experts.planner import PlannerConfig, PredictiveSampling
from tests.test_ppo import permutation_p_value

TINY = PlannerConfig(n_samples=6, horizon=0.1, n_knots=3, noise=0.3)


def _run(task, config, seeds, steps):
    """Actions and rewards of the planner over ``steps`` control steps of episodes ``seeds``."""
    p = PredictiveSampling(task, config)
    venv = tasks.load_vec(task, len(seeds))
    p.attach(venv)
    p.reset(np.asarray(seeds))
    obs, _ = venv.reset(seeds)
    actions, rewards, predicted = [], [], []
    for _ in range(steps):
        a = venv.check_actions(p(obs))
        obs, r, _, _ = venv.step(a)
        actions.append(a)
        rewards.append(r)
        predicted.append(p.last_first_reward.copy())
    return np.array(actions), np.array(rewards), np.array(predicted)


@pytest.mark.parametrize("task", ["walker", "hopper", "ant", "humanoid", "halfcheetah"])
def test_the_planner_predicts_the_tasks_own_reward_exactly(task):
    # Its model copy only adds sensors, and it scores with the task's batch_reward: the reward
    # predicted for the step it takes is the reward the environment then pays.
    _, rewards, predicted = _run(task, TINY, [3], 12)
    np.testing.assert_allclose(predicted, rewards, rtol=0, atol=1e-9)
    assert np.ptp(rewards) > 0       # not a constant that would match trivially


@pytest.mark.parametrize("task", ["hopper", "humanoid"])
def test_the_planner_predicts_the_environments_data_over_its_whole_horizon(task):
    # Every rebuilt MjData field after every step of an open-loop sequence, not only the
    # first reward: the state/sensor index arithmetic, and the touch and force sensors,
    # which the environment holds from an earlier stage of its last physics step.
    p = PredictiveSampling(task, TINY)
    venv = tasks.load_vec(task, 1)
    p.attach(venv)
    venv.reset([7])
    rng = np.random.default_rng(1)
    for _ in range(20):
        venv.step(rng.uniform(-1, 1, (1, venv.spec.act_dim)))
    H = 6
    controls = rng.uniform(p.low, p.high, (1, H, venv.spec.act_dim))
    fields = p.predicted_fields(p._states(1), controls)
    predicted = p.predict(p._states(1), controls)[0]
    for j in range(H):
        _, reward, _, _ = venv.step(controls[:, j])
        d = venv.data(0)
        for k, v in fields.items():
            np.testing.assert_allclose(v[j], getattr(d, k), rtol=1e-9, atol=1e-9, err_msg=k)
        assert abs(predicted[j] - reward[0]) < 1e-9


def test_plans_interpolate_their_knots_and_shift_one_step():
    p = PredictiveSampling("walker", PlannerConfig(n_samples=2, horizon=0.25, n_knots=4))
    H, t = p.H, np.arange(p.H)
    a, b = np.random.default_rng(0).normal(size=(2, 6))
    linear = a + b * p.knot_t[:, None]                     # a plan linear in time
    np.testing.assert_allclose(p._controls(linear[None])[0], a + b * t[:, None], atol=1e-12)
    shifted = p._shift(linear[None])[0]
    np.testing.assert_allclose(shifted, a + b * np.minimum(p.knot_t + 1, H - 1)[:, None],
                               atol=1e-12)
    kinked = np.zeros((1, 4, 6))
    kinked[0, 1] = 1.0                                     # a tent: 0, 1, 0, 0
    c = p._controls(kinked)[0, :, 0]
    assert c[0] == 0 and c[-1] == 0 and c.max() <= 1 and np.all(c >= 0)
    np.testing.assert_allclose(p._shift(kinked)[0, -1], 0)  # held at its end


def test_replanning_every_k_steps_plans_on_steps_1_k_plus_1_and_follows_the_plan_between():
    p = PredictiveSampling("walker", PlannerConfig(**{**TINY.__dict__, "replan_every": 3}))
    venv = tasks.load_vec("walker", 1)
    p.attach(venv)
    p.reset([2])
    obs, _ = venv.reset([2])
    planned, original = [], p.plan
    p.plan = lambda states: planned.append(p.t) or original(states)
    for _ in range(7):
        expected = p.nominal[:, 0].copy()
        action = p(obs)
        if p.t not in planned:
            np.testing.assert_array_equal(action, expected)
            assert p.last_first_reward is None
        obs, _, _, _ = venv.step(venv.check_actions(action))
    assert planned == [1, 4, 7]


def test_a_task_whose_reward_reads_what_the_rollouts_do_not_give_is_refused():
    with pytest.raises(ValueError, match="geom_xpos"):
        PredictiveSampling("reacher1", TINY)


def test_the_planners_model_copy_steps_like_the_task():
    p = PredictiveSampling("walker", TINY)
    env = tasks.make("walker", seed=1)
    env.reset(seed=1)
    base = env.physics.model.ptr
    m = p.sensed.model
    assert m.nsensordata == base.nsensordata + 10 * (base.nbody - 1)
    np.testing.assert_array_equal(m.opt.timestep, base.opt.timestep)
    np.testing.assert_array_equal(m.actuator_ctrlrange, base.actuator_ctrlrange)


def test_the_planner_is_deterministic_and_each_episode_depends_on_its_seed_alone():
    a1, r1, _ = _run("hopper", TINY, [11], 5)
    a2, r2, _ = _run("hopper", TINY, [11], 5)
    np.testing.assert_array_equal(a1, a2)
    # The same episode beside another one, and with two rollout threads: the same actions.
    a3, _, _ = _run("hopper", TINY, [11, 12], 5)
    a4, _, _ = _run("hopper", PlannerConfig(**{**TINY.__dict__, "threads": 2}), [11], 5)
    np.testing.assert_array_equal(a1[:, 0], a3[:, 0])
    np.testing.assert_array_equal(a1, a4)
    # Another planner seed samples other plans.
    a5, _, _ = _run("hopper", PlannerConfig(**{**TINY.__dict__, "seed": 1}), [11], 5)
    assert not np.array_equal(a1, a5)


def test_the_planner_beats_random_actions():
    # halfcheetah's run reward is a cheap, unambiguous signal: 8 short episodes each.
    config = PlannerConfig(n_samples=16, horizon=0.15, n_knots=3, noise=0.5)
    steps, seeds = 150, list(range(8))
    _, planned, _ = _run("halfcheetah", config, seeds, steps)
    venv = tasks.load_vec("halfcheetah", len(seeds))
    venv.reset(seeds)
    rand = rollout.RandomPolicy("halfcheetah", seed=0)
    rand.reset(np.array(seeds))
    randoms = [venv.step(rand(np.zeros((len(seeds), 1))))[1] for _ in range(steps)]
    planned, randoms = planned.sum(0), np.array(randoms).sum(0)
    assert permutation_p_value(planned, randoms) < 0.01
    assert planned.mean() - randoms.mean() > 10      # 150 steps: at least 0.07 m/s more


def test_bad_settings_and_misuse_give_clear_errors():
    with pytest.raises(ValueError, match="n_samples must be at least 2"):
        PredictiveSampling("walker", PlannerConfig(n_samples=1))
    with pytest.raises(ValueError, match="unknown planning reward 'nope'.*humanoid-shaped"):
        PredictiveSampling("walker", PlannerConfig(planning_reward="nope"))
    with pytest.raises(tasks.UnknownTaskError, match="the tasks are"):
        PredictiveSampling("walkerr", TINY)
    p = PredictiveSampling("walker", TINY)
    with pytest.raises(RuntimeError, match="attach"):
        p(np.zeros((1, 24), np.float32))
    with pytest.raises(ValueError, match="cannot act in 'hopper'"):
        p.attach(tasks.load_vec("hopper", 1))


def test_planner_tasks_load_as_planners_and_write_their_settings(tmp_path):
    from dc_lesson.experts import DEFAULT_EXPERT
    for task in planner.PLANNERS:
        expert, info = load_expert(task, None if DEFAULT_EXPERT[task] == "planner"
                                   else "planner")
        assert isinstance(expert, PredictiveSampling) and info["kind"] == "planner"
        settings = dict(planner.PLANNERS[task].__dict__)
        del settings["threads"]      # not a setting of the expert: results do not depend on it
        assert info["config"] == settings
        written = planner.write_settings(task, command="test", directory=tmp_path)
        assert json.loads(planner.settings_path(task, tmp_path).read_text()) == written
    with pytest.raises(ValueError, match="planner experts exist for"):
        planner.write_settings("cartpole", directory=tmp_path)


def _record_collects(monkeypatch, key=lambda policy, kw: kw.get("first")):
    """Wraps rollout.collect to record key(policy, kwargs) of every call; returns the record
    and the original function."""
    calls, original = [], rollout.collect

    def recording(task, policy, *a, **kw):
        calls.append(key(policy, kw))
        return original(task, policy, *a, **kw)
    monkeypatch.setattr(rollout, "collect", recording)
    return calls, original


def test_an_interrupted_collection_resumes_to_the_same_episodes(tmp_path, monkeypatch):
    policy = rollout.RandomPolicy("cartpole", seed=4)
    part = tmp_path / "partial" / "cartpole-demos.npz"
    first = demos.collect_resumable("cartpole", policy, 2, 5, part, "fp", progress=False)
    assert json.loads(part.with_suffix(".json").read_text())["episodes"] == 2
    calls, original = _record_collects(monkeypatch)
    # "Interrupted" after 2 of 3: the rerun reads those 2 and collects only the third.
    resumed = demos.collect_resumable("cartpole", policy, 3, 5, part, "fp", progress=False)
    assert calls == [2]
    straight = original("cartpole", policy, 3, seed=5)
    for a, b in zip(resumed, straight):
        np.testing.assert_array_equal(a.actions, b.actions)
        np.testing.assert_array_equal(a.observations, b.observations)
    assert [t.seed for t in resumed[:2]] == [t.seed for t in first]
    # Another expert (another fingerprint) does not reuse the partial file.
    calls.clear()
    demos.collect_resumable("cartpole", policy, 3, 5, part, "other", progress=False)
    assert calls == [0, 1, 2]


def test_a_partial_file_is_reused_only_with_its_own_stamp(tmp_path, monkeypatch):
    policy = rollout.RandomPolicy("cartpole", seed=4)
    part = tmp_path / "cartpole-demos.npz"
    stamp = part.with_suffix(".json")
    demos.collect_resumable("cartpole", policy, 2, 5, part, "fp", progress=False)
    info = json.loads(stamp.read_text())
    calls, original = _record_collects(monkeypatch)

    def rerun(fingerprint="fp", seed=5):
        calls.clear()
        demos.collect_resumable("cartpole", policy, 2, seed, part, fingerprint, progress=False)
        return calls

    # Another seed, the same expert: the stored episodes are other episodes.
    assert rerun(seed=6) == [0, 1]
    assert rerun(seed=5) == [0, 1]       # the file now holds seed 6's: not seed 5's
    # A stamp that names another file (an interrupted run of another expert wrote its stamp
    # beside this file): not reused.
    stamp.write_text(json.dumps({**info, "sha256": "0" * 64}))
    assert rerun() == [0, 1]
    # A stamp of the older format (no sha256, written just before its file) is read when its
    # count covers the file, and not when the file holds more than it says.
    legacy = {k: v for k, v in json.loads(stamp.read_text()).items() if k != "sha256"}
    stamp.write_text(json.dumps(legacy))
    assert rerun() == []
    stamp.write_text(json.dumps({**legacy, "episodes": 1}))
    assert rerun() == [0, 1]
    stamp.write_text("not json")
    assert rerun() == [0, 1]


def test_the_two_stages_run_apart_and_give_the_file_of_one_run(tmp_path, monkeypatch):
    # A cheap planner in place of the walker's, so whole 1000-step episodes take seconds.
    cheap = PlannerConfig(n_samples=2, horizon=0.05, n_knots=2, noise=0.3)
    monkeypatch.setitem(planner.PLANNERS, "walker", cheap)
    kw = dict(n_demos=2, n_eval=3, progress=False, threads=1)
    straight = demos.make_demos("walker", variant="planner", directory=tmp_path / "straight", **kw)
    staged_dir = tmp_path / "staged"
    assert demos.make_demos("walker", variant="planner", directory=staged_dir, stage="eval", **kw) is None
    assert demos.make_demos("walker", variant="planner", directory=staged_dir, stage="demos", **kw) is None
    calls, _ = _record_collects(monkeypatch, lambda policy, kw: type(policy).__name__)
    staged = demos.make_demos("walker", variant="planner", directory=staged_dir, **kw)
    assert calls == ["RandomPolicy"]          # the planner's episodes were all on disk
    assert staged["sha256"] == straight["sha256"]
    assert staged["expert_return"] == straight["expert_return"]
    assert not list((staged_dir / "partial").glob("walker-planner-*"))
    # The evaluation stage split between two processes, one from its start and one from
    # episode 1 on: the same file again, and the planner runs no episode twice.
    split_dir = tmp_path / "split"
    kw3 = {**kw, "n_eval": 4}
    straight3 = demos.make_demos("walker", variant="planner", directory=tmp_path / "straight3", **kw3)
    calls.clear()
    assert demos.make_demos("walker", variant="planner", directory=split_dir, stage="eval", first=1, **kw3) is None
    assert demos.make_demos("walker", variant="planner", directory=split_dir, stage="eval", **kw3) is None
    assert demos.make_demos("walker", variant="planner", directory=split_dir, stage="demos", **kw3) is None
    assert calls.count("PredictiveSampling") == 2 + 2   # 2 demos, 2 evaluation episodes
    split = demos.make_demos("walker", variant="planner", directory=split_dir, **kw3)
    assert split["sha256"] == straight3["sha256"]
    assert split["expert_return"] == straight3["expert_return"]
    with pytest.raises(ValueError, match="first applies to stage 'eval'"):
        demos.make_demos("walker", variant="planner", directory=split_dir, stage="demos", first=1, **kw3)
    with pytest.raises(ValueError, match="stages are: demos, eval"):
        demos.make_demos("walker", variant="planner", directory=staged_dir, stage="random", **kw)
    with pytest.raises(ValueError, match="without --stage"):
        demos.make_demos("cartpole", directory=staged_dir, stage="demos", **kw)


def test_an_episode_of_a_planner_renders():
    # the planner reads the simulator state of the environment it acts in: the rendered
    # episode must hand it a running one (a batched copy left behind would crash it)
    from dc_lesson.viz import render
    frames = render.episode_frames("walker", PredictiveSampling("walker", TINY), n_steps=2,
                                   every=1, height=24, width=32)
    assert len(frames) == 3 and frames[0].shape == (24, 32, 3)
    assert not np.array_equal(frames[0], frames[2])
