"""The ten task ports: specs, rewards, seeding, and the documented behaviour of each task."""

import mujoco
import numpy as np
import pytest

from dc_lesson import tasks
from dc_lesson.tasks import reacher

ALL = list(tasks.NAMES)


def test_ten_tasks_in_the_papers_order():
    assert tasks.NAMES == ("cartpole", "reacher1", "reacher2", "reacher4", "hopper", "walker",
                           "halfcheetah", "halfcheetah2", "ant", "humanoid")


@pytest.mark.parametrize("name", ALL)
def test_spec_matches_the_environment_and_rewards_stay_in_unit_interval(name):
    spec = tasks.spec(name)
    env = tasks.make(name, seed=0)
    obs = env.reset()
    assert obs.shape == (spec.obs_dim,) and obs.dtype == np.float32
    assert env.action_low.shape == (spec.act_dim,)
    np.testing.assert_array_equal(env.action_low, -1)
    np.testing.assert_array_equal(env.action_high, 1)
    assert round(spec.control_timestep / env.physics.timestep()) == spec.n_sub_steps
    assert env.mode_feature().shape == (spec.mode_dim,)
    assert spec.horizon == 1000
    rng = np.random.default_rng(0)
    rewards = []
    for t in range(spec.horizon):
        obs, r, done = env.step(rng.uniform(-1, 1, spec.act_dim))
        rewards.append(r)
        assert done == (t == spec.horizon - 1)
        assert np.all(np.isfinite(obs))
    assert 0.0 <= min(rewards) and max(rewards) <= 1.0
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(spec.act_dim))


@pytest.mark.parametrize("name", ALL)
def test_same_seed_and_actions_give_identical_trajectories(name):
    spec = tasks.spec(name)
    actions = np.random.default_rng(1).uniform(-1, 1, (60, spec.act_dim))

    def run(seed):
        env = tasks.make(name)
        out = [env.reset(seed=seed)]
        rews = []
        for a in actions:
            o, r, _ = env.step(a)
            out.append(o)
            rews.append(r)
        return np.stack(out), np.array(rews)

    o1, r1 = run(7)
    o2, r2 = run(7)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(r1, r2)
    o3, _ = run(8)
    assert not np.array_equal(o1[0], o3[0]), "two seeds gave the same initial state"


@pytest.mark.parametrize("name", ALL)
def test_load_seed_reaches_the_tasks_randomness(name):
    a = tasks.make(name, seed=3).reset()
    b = tasks.make(name, seed=3).reset()
    c = tasks.make(name, seed=4).reset()
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("name", tasks.NAMES)
def test_dm_env_gymnasium_and_fast_faces_agree_over_a_whole_episode(name):
    """The three faces of a port give the same observations and rewards at every step of a
    whole episode, and end it together: dm_env with LAST (discount 1: a time limit), Gymnasium
    with truncated=True, terminated=False, the fast engine with done.  A batch of one of the
    VecEnv engine (what training uses) agrees too."""
    import gymnasium
    from dm_env import StepType
    spec = tasks.spec(name)
    actions = np.random.default_rng(2).uniform(-1, 1, (spec.horizon, spec.act_dim))
    fast, dm = tasks.make(name), tasks.load(name)
    gym = gymnasium.make(tasks.gym_id(name))
    vec = tasks.load_vec(name, 1)
    o = fast.reset(seed=5)
    dm.task.random.seed(5)
    ts = dm.reset()
    g, info = gym.reset(seed=5)
    v, _ = vec.reset([5])
    assert ts.step_type == StepType.FIRST
    np.testing.assert_array_equal(o, g)
    np.testing.assert_array_equal(o, v[0])
    np.testing.assert_array_equal(o, tasks.base.flatten_observation(ts.observation))
    assert info["mode_feature"].shape == (spec.mode_dim,)
    for t, a in enumerate(actions):
        o, r, done = fast.step(a)
        ts = dm.step(a)
        g, gr, terminated, truncated, info = gym.step(a.astype(np.float32).astype(np.float64))
        v, vr, _, vdone = vec.step(a[None])
        last = t == spec.horizon - 1
        np.testing.assert_array_equal(o, tasks.base.flatten_observation(ts.observation))
        np.testing.assert_array_equal(o, v[0])
        assert r == ts.reward == vr[0]
        assert done == vdone == last == truncated == ts.last()
        assert terminated is False
        if last:
            assert ts.discount == 1.0   # a time limit, not a terminal state
        # Gymnasium steps float32 actions: the same applied action only where float32 is exact
        if np.array_equal(a.astype(np.float32), a):
            np.testing.assert_array_equal(o, g)
    assert t == spec.horizon - 1


def test_gymnasium_face_spaces_seeding_and_info():
    import gymnasium
    env = gymnasium.make("dc_lesson/reacher4-v0")
    spec = tasks.spec("reacher4")
    assert env.observation_space.shape == (spec.obs_dim,)
    assert env.observation_space.dtype == np.float32
    assert env.action_space.shape == (spec.act_dim,)
    assert np.all(env.action_space.low == -1) and np.all(env.action_space.high == 1)
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    c, _ = env.reset(seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    obs, r, term, trunc, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    assert 0.0 <= r <= 1.0 and not term and not trunc
    assert set(info) >= {"mode_feature", "t"} and info["t"] == 1
    # the module:id form imports the registering module itself
    assert gymnasium.make("dc_lesson.tasks:dc_lesson/cartpole-v0").observation_space.shape == (5,)


def test_unknown_task_names_the_valid_ones():
    with pytest.raises(tasks.UnknownTaskError) as e:
        tasks.make("nope")
    for name in tasks.NAMES:
        assert name in str(e.value)
    assert isinstance(e.value, KeyError)


@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros((1, 2)), [np.nan, 0.0], 0.5])
def test_wrong_action_gives_a_clear_error(bad):
    env = tasks.make("reacher1", seed=0)
    env.reset()
    with pytest.raises(tasks.ActionError, match="reacher1"):
        env.step(bad)


def test_actions_are_clipped_to_the_bounds_as_mujoco_would():
    big, clipped = tasks.make("cartpole", seed=0), tasks.make("cartpole", seed=0)
    big.reset(), clipped.reset()
    np.testing.assert_array_equal(big.step([5.0])[0], clipped.step([1.0])[0])


def _place_fingertip(env, xy):
    """Sets the arm's joints so that the fingertip is at ``xy`` (two-link inverse kinematics)."""
    p = env.physics
    l1 = 0.12
    l2 = 0.12
    x, y = xy
    c2 = (x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    q2 = np.arccos(np.clip(c2, -1, 1))
    q1 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
    p.data.qpos[:] = [q1, q2]
    p.data.qvel[:] = 0
    p.forward()


@pytest.mark.parametrize("k", [1, 2, 4])
def test_each_reacher_target_is_rewarded_and_classified(k):
    env = tasks.make(f"reacher{k}", seed=0)
    env.reset()
    targets = reacher.target_positions(k)
    assert len(env.spec.modes) == (k if k > 1 else 0)
    for i, xy in enumerate(targets):
        _place_fingertip(env, xy)
        np.testing.assert_allclose(env.mode_feature(), xy, atol=1e-6)
        assert env.task.get_reward(env.physics) == 1.0
        assert env.task.classify_mode(env.mode_feature()[None])[0] == i
    _place_fingertip(env, -targets.mean(0) + np.array([0.0, 0.02]) if k > 1 else [0.05, -0.15])
    assert env.task.get_reward(env.physics) == 0.0


def _edge_values(rng):
    """Values a tolerance must get right: both signs of zero, the bounds and margins, just
    inside and outside them, infinities, NaN, and plenty of ordinary numbers."""
    special = [0.0, -0.0, 1.0, -1.0, 2.0, -2.0, 5.0, 10.0, -10.0, 20.0, np.nextafter(10.0, 0),
               np.nextafter(1.0, 0), np.nextafter(1.0, 2), 1e-300, -1e-300, np.inf, -np.inf,
               np.nan, 1.2, np.nextafter(1.2, 0), 0.6, 0.5, np.nextafter(0.5, 1)]
    return np.concatenate([rng.normal(0, s, 4000) for s in (0.01, 1.0, 5.0, 30.0)]
                          + [np.array(special)])


def test_the_ports_tolerances_are_dm_controls_to_the_bit():
    """base's tolerances are dm_control's ``rewards.tolerance`` in the forms the ports call
    it, float for float (a stored run's rewards must not move)."""
    from dm_control.utils import rewards
    from dc_lesson.tasks import base
    x = _edge_values(np.random.default_rng(0))
    with np.errstate(invalid="ignore", over="ignore"):   # inf - inf inside dm_control's
        for margin in (2, 5):
            np.testing.assert_array_equal(base.gaussian_tolerance(x, margin),
                                          rewards.tolerance(x, margin=margin))
        np.testing.assert_array_equal(
            base.quadratic_tolerance(x),
            rewards.tolerance(x, margin=1, value_at_margin=0, sigmoid="quadratic"))
        np.testing.assert_array_equal(
            base.linear_tolerance_above(x, 10.0, 10.0),
            rewards.tolerance(x, bounds=(10.0, float("inf")), margin=10.0, value_at_margin=0,
                              sigmoid="linear"))
        # the walker's two (stand height 1.2, move speed 1 m/s)
        np.testing.assert_array_equal(base.gaussian_tolerance_above(x, 1.2, 0.6),
                                      rewards.tolerance(x, bounds=(1.2, float("inf")),
                                                        margin=0.6))
        np.testing.assert_array_equal(
            base.linear_tolerance_above(x, 1.0, 0.5, value_at_margin=0.5),
            rewards.tolerance(x, bounds=(1.0, float("inf")), margin=0.5, value_at_margin=0.5,
                              sigmoid="linear"))


@pytest.mark.parametrize("k", [1, 4])
def test_reacher_outputs_are_the_suite_style_expressions_to_the_bit(k):
    """The reacher's interleaved (cos, sin) and its indicator reward against the expressions
    they replace (np.stack of four calls; the tolerance of the norm), with fingertips exactly
    on a target's edge and a hair inside and outside it."""
    from dm_control.utils import rewards
    from dc_lesson.tasks.base import Batch
    env = tasks.make(f"reacher{k}", seed=0)
    task, model = env.task, env.physics.model.ptr
    ids = task.ids(model)
    rng = np.random.default_rng(k)
    n = 512
    b = Batch.__new__(Batch)
    b.ids = ids
    b.qpos = rng.uniform(-40, 40, (n, 2))
    b.qvel = rng.normal(0, 3, (n, 2))
    b.geom_xpos = np.zeros((n, model.ngeom, 3))
    for i, g in enumerate(ids["targets"]):
        b.geom_xpos[:, g, :2] = reacher.target_positions(k)[i]
    # fingertips at the edge of target 0 (and just off it), and anywhere
    angle = rng.uniform(0, 2 * np.pi, n)
    radius = np.where(np.arange(n) % 4 == 0, ids["radii"],
                      np.where(np.arange(n) % 4 == 1, np.nextafter(ids["radii"], 1),
                               rng.uniform(0, 0.3, n)))
    tip = reacher.target_positions(k)[0] + radius[:, None] * np.stack(
        [np.cos(angle), np.sin(angle)], axis=1)
    b.geom_xpos[:, ids["finger"], :2] = tip
    q = b.qpos
    want = np.stack([np.cos(q[:, 0]), np.sin(q[:, 0]), np.cos(q[:, 1]), np.sin(q[:, 1])], axis=1)
    np.testing.assert_array_equal(task.batch_observation(b)["position"], want)
    to_targets = b.geom_xpos[:, ids["targets"], :2] - tip[:, None]
    want_r = rewards.tolerance(np.linalg.norm(to_targets, axis=2), (0, ids["radii"])).max(axis=1)
    got_r = task.batch_reward(b)
    np.testing.assert_array_equal(got_r, want_r)
    assert 0 < got_r.mean() < 1   # both sides of the edge were tried


def test_reacher_targets_are_not_observed():
    """Two reachers with different targets observe the same numbers for the same arm state."""
    a, b = tasks.make("reacher1", seed=0), tasks.make("reacher4", seed=0)
    np.testing.assert_array_equal(a.reset(), b.reset())


@pytest.mark.parametrize("speed", [12.0, -12.0, 5.0, -5.0])
def test_halfcheetah2_rewards_running_either_way(speed):
    env2, env1 = tasks.make("halfcheetah2", seed=0), tasks.make("halfcheetah", seed=0)
    for env in (env2, env1):
        env.reset()
        env.physics.data.qvel[0] = speed  # rootx: the torso's forward velocity
        env.physics.forward()
    r2 = env2.task.get_reward(env2.physics)
    r1 = env1.task.get_reward(env1.physics)
    assert r2 == pytest.approx(min(abs(speed) / 10, 1), abs=0.05)
    assert r1 == pytest.approx(min(max(speed, 0) / 10, 1), abs=0.05)
    assert env2.task.classify_mode(env2.mode_feature()[None])[0] == (0 if speed > 0 else 1)


def test_ant_is_rewarded_for_running_forward_while_healthy():
    env = tasks.make("ant", seed=0)
    env.reset()
    env.physics.data.qpos[2] = 0.55
    env.physics.data.qvel[0] = 3.5
    env.physics.forward()
    assert env.task.get_reward(env.physics) == pytest.approx(1.0, abs=0.02)
    env.physics.data.qvel[0] = -1.0
    env.physics.forward()
    assert env.task.get_reward(env.physics) == 0.0


def test_spec_table_has_a_row_per_task():
    rows = tasks.spec_table()
    assert [r["task"] for r in rows] == list(tasks.NAMES)
    assert all(r["differs from the paper"] for r in rows)


SUITE_ORIGINALS = {
    "cartpole": "dm_control.suite.cartpole:Balance",
    "walker": "dm_control.suite.walker:PlanarWalker",
    "halfcheetah": "dm_control.suite.cheetah:Cheetah",
    "humanoid": "dm_control.suite.humanoid:Humanoid",
}


@pytest.mark.parametrize("name", list(SUITE_ORIGINALS))
def test_batched_ports_of_suite_tasks_equal_the_suites_own_functions(name):
    """Our vectorised observation and reward are the suite task's, term for term."""
    import importlib
    mod, cls = SUITE_ORIGINALS[name].split(":")
    original = getattr(importlib.import_module(mod), cls)
    env = tasks.make(name, seed=1)
    env.reset()
    rng = np.random.default_rng(3)
    for _ in range(120):
        env.step(rng.uniform(-1, 1, env.spec.act_dim))
        ours = env.task.get_observation(env.physics)
        theirs = original.get_observation(env.task, env.physics)
        assert list(ours) == list(theirs)
        for key in ours:
            np.testing.assert_allclose(ours[key], theirs[key], rtol=1e-12, atol=1e-12,
                                       err_msg=key)
        assert env.task.get_reward(env.physics) == pytest.approx(
            original.get_reward(env.task, env.physics), rel=1e-12, abs=1e-12)


def _gym_hopper_reward(env, action):
    """Gym's Hopper-v5 reward, written out from its documentation, with the centre of mass's
    speed for Gym's torso speed: healthy_reward + forward_reward - ctrl_cost."""
    qpos, qvel = env.physics.data.qpos, env.physics.data.qvel
    z, angle, state = qpos[1], qpos[2], np.concatenate([qpos[2:], qvel])
    is_healthy = z > 0.7 and -0.2 < angle < 0.2 and np.all((-100 < state) & (state < 100))
    return is_healthy * 1.0 + env.physics.speed() - 1e-3 * np.sum(np.square(action))


def test_hopper_pays_gyms_reward_over_four_clipped_to_the_unit_interval():
    env = tasks.make("hopper", seed=0)
    env.reset()
    assert env.physics.height() > 1.2, "the hopper starts standing, as Gym's does"
    rng = np.random.default_rng(0)
    seen = []
    for _ in range(300):
        a = rng.uniform(-1, 1, 3)
        _, r, _ = env.step(a)
        healthy = env.physics.height() > 0.7 and abs(env.physics.data.qpos[2]) < 0.2
        expected = np.clip(_gym_hopper_reward(env, a) / 4, 0, 1) if healthy else 0.0
        assert r == pytest.approx(expected, abs=1e-12)
        seen.append(healthy)
    assert any(seen) and not all(seen)   # random actions make it fall: both cases checked
    # Standing still pays a quarter; 3 m/s or more in full; a fallen hopper nothing.
    env.reset(seed=1)
    assert env.task.get_reward(env.physics) == pytest.approx(0.25, abs=0.01)
    env.physics.data.qvel[0] = 3.5
    env.physics.forward()
    assert env.task.get_reward(env.physics) == pytest.approx(1.0)
    env.physics.data.qpos[2] = 0.3    # rooty: the torso tilted past Gym's 0.2 rad
    env.physics.forward()
    assert env.task.get_reward(env.physics) == 0.0


def test_hopper_observes_what_gym_observes():
    # qpos without the forward position, and the velocities clipped to +-10.
    env = tasks.make("hopper", seed=0)
    env.reset()
    env.physics.data.qvel[:] = [12, -3, 0.5, -20, 1, 2]
    env.physics.forward()
    obs = env.observation()
    np.testing.assert_allclose(obs[:5], env.physics.data.qpos[1:], rtol=1e-6)
    np.testing.assert_allclose(obs[5:], [10, -3, 0.5, -10, 1, 2], rtol=1e-6)


def test_hopper_model_is_gyms():
    # Gym's Hopper-v5 numbers: 3 motors of gear 200, RK4 at 2 ms, frame skip 4, torso at 1.25 m.
    env = tasks.make("hopper", seed=0)
    m = env.physics.model
    assert (m.nq, m.nv, m.nu) == (6, 6, 3)
    np.testing.assert_array_equal(m.actuator_gear[:, 0], [200, 200, 200])
    assert m.opt.timestep == 0.002 and env.spec.n_sub_steps == 4
    assert m.qpos0[1] == 1.25


@pytest.mark.parametrize("name", ALL)
def test_vec_env_equals_single_envs_exactly(name):
    spec = tasks.spec(name)
    seeds = [3, 4, 5]
    venv = tasks.load_vec(name, 4)
    obs_v, feat_v = venv.reset(seeds)
    singles = [tasks.make(name) for _ in seeds]
    obs_s = np.stack([e.reset(seed=s) for e, s in zip(singles, seeds)])
    np.testing.assert_array_equal(obs_v, obs_s)
    np.testing.assert_array_equal(feat_v, np.stack([e.mode_feature() for e in singles]))
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = rng.uniform(-1.2, 1.2, (len(seeds), spec.act_dim))
        obs_v, rew_v, feat_v, done = venv.step(a)
        outs = [e.step(ai) for e, ai in zip(singles, a)]
        np.testing.assert_array_equal(obs_v, np.stack([o for o, _, _ in outs]))
        np.testing.assert_array_equal(rew_v, np.array([r for _, r, _ in outs]))
        np.testing.assert_array_equal(feat_v, np.stack([e.mode_feature() for e in singles]))
    with pytest.raises(tasks.ActionError, match="shape"):
        venv.step(np.zeros((4, spec.act_dim)))


@pytest.mark.parametrize("name", ALL)
def test_the_batched_engine_equals_copy_by_copy_stepping_over_a_whole_episode(name):
    """mujoco.batch against each copy on its own Physics: every observation, reward, mode
    feature and state of a whole episode, with a copy restarted alone half way (as PPO's
    training-only termination does) and states read in two signatures."""
    spec = tasks.spec(name)
    fast, ref = tasks.load_vec(name, 3), tasks.load_vec(name, 3, batched=False)
    assert fast.batched and not ref.batched
    # fewer episodes than copies: the third sits idle
    np.testing.assert_array_equal(fast.reset([7, 8])[0], ref.reset([7, 8])[0])
    rng = np.random.default_rng(1)
    for t in range(spec.horizon):
        a = rng.uniform(-1, 1, (2, spec.act_dim))
        got, want = fast.step(a), ref.step(a)
        for g, w in zip(got[:3], want[:3]):
            np.testing.assert_array_equal(g, w)
        if t == spec.horizon // 2:
            np.testing.assert_array_equal(fast.reset_one(1, 99), ref.reset_one(1, 99))
        if t % 250 == 0:
            for sig in (mujoco.mjtState.mjSTATE_INTEGRATION, mujoco.mjtState.mjSTATE_FULLPHYSICS):
                np.testing.assert_array_equal(fast.get_states(sig), ref.get_states(sig))
    assert got[3] and want[3]
    with pytest.raises(ValueError, match="not running"):
        fast.reset_one(2, 0)


def test_the_hopper_s_drawn_floor_outlasts_its_expert_and_changes_no_physics():
    import numpy as np
    from dc_lesson import data, tasks
    from dc_lesson.tasks import hopper
    # how far the expert's demonstrations get: the integral of the forward speed (obs 5)
    reach = max(t.observations[:, 5].sum() * hopper.SPEC.control_timestep
                for t in data.load_demos("hopper").trajectories)
    env = tasks.load("hopper", seed=0)
    floor = env.physics.model.geom("floor")
    assert floor.size[0] > 1.5 * reach        # the picture: the body stays on the floor

    def states(xml):
        physics = hopper.Physics.from_xml_string(xml, {})
        rng, out = np.random.default_rng(0), []
        for _ in range(300):
            physics.set_control(rng.uniform(-1, 1, 3))
            physics.step()
            out.append(physics.data.qpos.copy())
        return np.array(out)

    xml, _ = hopper.get_model_and_assets()
    narrow = xml.replace('size="60 60 .125"', 'size="20 20 .125"')
    assert narrow != xml
    np.testing.assert_array_equal(states(xml), states(narrow))   # a plane collides everywhere
