"""Trained-expert plumbing: recipes, the coin-flip mixture, and clear errors."""

import numpy as np
import pytest

from dc_lesson.data import rollout
from dc_lesson import tasks
from dc_lesson.experts import load_expert, trained


def test_every_locomotion_task_has_a_recipe_on_its_own_task():
    from dc_lesson.experts import network
    for task, units in trained.EXPERT_UNITS.items():
        tasks.check_name(task)
        for unit in units:   # PPO's recipe, or (walker, ant, humanoid) SAC's and DAgger's
            assert unit in trained.RECIPES or unit in network.SAC_RECIPES
            if unit in trained.RECIPES:
                assert task.startswith(trained.RECIPES[unit].task[:len("halfcheetah")])
    assert set(trained.EXPERT_UNITS) | {"cartpole", "reacher1", "reacher2", "reacher4"} == \
        set(tasks.NAMES)
    assert set(trained.PPO_TASKS) | set(network.SAC_RECIPES) == set(trained.EXPERT_UNITS)


def test_coin_flip_mixture_follows_the_episode_seed_and_is_fair():
    forward = lambda obs: np.ones((len(obs), 6))     # noqa: E731
    backward = lambda obs: -np.ones((len(obs), 6))   # noqa: E731
    mix = trained.CoinFlipMixture([forward, backward])
    seeds = rollout.episode_seeds(0, 400)
    mix.reset(seeds)
    first = mix.chosen.copy()
    mix.reset(seeds)
    np.testing.assert_array_equal(first, mix.chosen)
    share = first.mean()
    assert abs(share - 0.5) < 4 * np.sqrt(0.25 / len(seeds))
    a = mix(np.zeros((len(seeds), 17)))
    np.testing.assert_array_equal(a[:, 0], np.where(first == 0, 1.0, -1.0))
    with pytest.raises(RuntimeError, match="reset"):
        trained.CoinFlipMixture([forward])(np.zeros((3, 17)))


def test_backward_reward_mirrors_the_forward_velocity():
    class B:
        next_obs = np.zeros((2, 3, 17))
    B.next_obs[..., 8] = [[-12, -5, 3], [0, -10, 10]]
    np.testing.assert_allclose(trained.backward_running_reward(B),
                               [[1, 0.5, 0], [0, 1, 0]])


def test_a_missing_trained_expert_says_how_to_train_it(tmp_path):
    with pytest.raises(trained.ExpertMissing, match="dc-lesson expert train --task walker"):
        trained.load_trained_expert("walker", directory=tmp_path)
    with pytest.raises(ValueError, match="no training recipe"):
        trained.train_unit("nope")


def test_training_a_unit_writes_a_loadable_policy_and_resumes(tmp_path):
    meta = trained.train_unit("halfcheetah", total_steps=8192, directory=tmp_path,
                              progress=False)
    assert meta["steps"] == 8192 and meta["seed"] == 0
    net = trained.load_unit("halfcheetah", directory=tmp_path)
    assert net.meta["task"] == "halfcheetah"
    assert (tmp_path / "checkpoints" / "halfcheetah.ckpt").exists()
    policy, info = trained.load_trained_expert("halfcheetah", directory=tmp_path)
    assert info["kind"] == "trained"
    traj = rollout.collect("halfcheetah", policy, 1, seed=0, max_steps=5)[0]
    assert traj.actions.shape == (5, 6)
    # A finished checkpoint resumes as done: nothing retrained, the same policy written.
    again = trained.train_unit("halfcheetah", total_steps=8192, directory=tmp_path,
                               progress=False)
    assert again["steps"] == 8192
    for a, b in zip(net.parameters(), trained.load_unit("halfcheetah", tmp_path).parameters()):
        assert np.array_equal(a.detach().numpy(), b.detach().numpy())


def test_load_expert_covers_every_task_or_says_how_to_make_it():
    for task in tasks.NAMES:
        try:
            policy, info = load_expert(task)
        except trained.ExpertMissing as e:
            assert "dc-lesson expert train" in str(e)
        else:
            assert callable(policy) and info["kind"] in ("scripted", "trained", "planner")


def test_stored_learning_curves_match_their_training_records():
    # The book plots these; a unit's curve must end at the steps its record says it trained.
    import json
    for unit in ("halfcheetah", "hopper", "walker-ppo", "ant-ppo"):
        curve = trained.learning_curve(unit)
        meta = json.loads(trained.unit_paths(unit)["meta"].read_text())
        assert curve["task"] == trained.RECIPES[unit].task
        assert np.all(np.diff(curve["steps"]) > 0)
        assert curve["steps"][-1] <= meta["steps"] == meta["config"]["total_steps"] // 4096 * 4096
        assert np.isfinite(curve["episode_return"]).all()
    with pytest.raises(trained.ExpertMissing, match="train_unit"):
        trained.learning_curve("humanoid-ppo")


def test_chapter_00s_reading_of_the_learning_curves_holds():
    # Chapter 00 says: the cheetahs and the hopper clear their floors within a million steps
    # (the hopper's training episodes end at a fall, for training only); the walker's and the
    # ant's PPO runs stay below theirs after 5M steps, and their SAC runs reach them.
    from dc_lesson.experts import floors

    def curve(unit):
        c = trained.learning_curve(unit)
        return c["steps"], c["episode_return"], floors.FLOORS[c["task"]]

    for unit in ("halfcheetah", "halfcheetah-backward", "hopper"):
        s, r, floor = curve(unit)
        assert (r[s <= 1_000_000] >= floor).any()
    for unit in ("walker-ppo", "ant-ppo"):
        s, r, floor = curve(unit)
        assert s[-1] >= 4_900_000 and r.max() < floor
    from dc_lesson.experts import DEFAULT_EXPERT, network
    for task in ("walker", "ant"):
        c = network.sac_curve(task)
        assert c["done"] and c["eval_return"].max() >= floors.FLOORS[task]
        assert DEFAULT_EXPERT[task] == "network"
    assert trained.RECIPES["hopper"].config.terminate == "hopper-fall"


def test_a_unit_trained_before_a_new_ppo_knob_still_counts_as_trained(tmp_path, monkeypatch):
    # halfcheetah.json predates PPOConfig.terminate: the missing knob takes its default.
    import json
    import shutil
    meta = json.loads(trained.unit_paths("halfcheetah")["meta"].read_text())
    assert "terminate" not in meta["config"]
    for f in ("policy", "meta"):
        shutil.copy(trained.unit_paths("halfcheetah")[f], trained.unit_paths("halfcheetah",
                                                                             tmp_path)[f])
    shutil.copy(str(trained.unit_paths("halfcheetah")["policy"]) + ".sha256", tmp_path)

    def no_training(*args, **kwargs):
        raise AssertionError("retrained a unit that was already trained")

    monkeypatch.setattr(trained, "train", no_training)
    assert trained.train_unit("halfcheetah", directory=tmp_path, progress=False)["steps"] == \
        meta["steps"]
