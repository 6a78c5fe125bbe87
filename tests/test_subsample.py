"""GAIL's subsampled demonstrations (``data.subsample``): which pairs are kept, and which of
the learners' readers see them (the kept pairs) or the whole episodes."""

import numpy as np
import pytest
import torch

from dc_lesson import data
from dc_lesson.algorithms import bc, dc, pwil
from dc_lesson.algorithms.base import LearnerInputError
from dc_lesson.data import TrajectoryError
from dc_lesson.evaluation import evaluate


@pytest.fixture(scope="module")
def demos():
    return data.load_demos("reacher1", n_trajectories=4)


def _offsets(sub):
    return [int(t.kept[0]) for t in sub.trajectories]


def test_each_demonstration_keeps_every_kth_pair_from_an_offset_below_k(demos):
    for every in (1, 7, 20):
        sub = data.subsample(demos, every=every, seed=3)
        for t, whole in zip(sub.trajectories, demos.trajectories):
            offset = int(t.kept[0])
            assert 0 <= offset < every
            np.testing.assert_array_equal(t.kept, np.arange(offset, len(whole), every))
            # the arrays stay the whole episode
            np.testing.assert_array_equal(t.observations, whole.observations)
            assert t.ret == whole.ret and len(t) == len(whole)
    assert sub.manifest["subsample"] == {"every": 20, "seed": 3}


def test_the_offsets_are_drawn_per_demonstration_from_the_seed(demos):
    a, b = data.subsample(demos, seed=5), data.subsample(demos, seed=5)
    assert _offsets(a) == _offsets(b)
    rng = np.random.default_rng(5)   # one draw per demonstration, in order (the docstring)
    assert _offsets(a) == [int(rng.integers(20)) for _ in demos.trajectories]
    # the first k demonstrations are subsampled alike whatever follows (nested subsets)
    first = data.subsample(data.load_demos("reacher1", n_trajectories=2), seed=5)
    assert _offsets(first) == _offsets(a)[:2]
    many = {tuple(_offsets(data.subsample(demos, seed=s))) for s in range(6)}
    assert len(many) > 1, "the seed does not move the offsets"


def test_bc_pairs_of_a_subsample_are_the_selected_rows(demos):
    sub = data.subsample(demos, seed=1)
    obs, act = bc.pairs(sub)
    want_obs = np.concatenate([t.observations[:-1][t.kept] for t in sub.trajectories])
    want_act = np.concatenate([t.actions[t.kept] for t in sub.trajectories])
    assert torch.equal(obs, torch.from_numpy(want_obs))
    assert torch.equal(act, torch.from_numpy(want_act))
    assert len(obs) == sum(len(t.kept) for t in sub.trajectories)
    np.testing.assert_array_equal(sub.observations, want_obs)   # the pair properties agree
    np.testing.assert_array_equal(sub.actions, want_act)
    assert len(sub.mode_features) == len(want_obs)
    assert [len(o) for o, _ in bc.episodes(sub)] == [len(t.kept) for t in sub.trajectories]
    assert not sub.whole().subsampled and len(sub.whole().observations) == \
        len(demos.observations)


def test_ordinary_demonstrations_are_read_as_before(demos):
    assert not demos.subsampled and demos.whole() is demos
    obs, act = bc.pairs(demos)
    assert torch.equal(obs, torch.from_numpy(
        np.concatenate([t.observations[:-1] for t in demos.trajectories])))
    assert torch.equal(act, torch.from_numpy(
        np.concatenate([t.actions for t in demos.trajectories])))
    # DC's P_w: every observation of each whole episode, the last too
    assert torch.equal(dc.expert_states(demos), torch.from_numpy(
        np.concatenate([t.observations for t in demos.trajectories])))


def test_dc_fits_its_flow_on_the_kept_states_only(demos):
    sub = data.subsample(demos, seed=2)
    want = np.concatenate([t.observations[t.kept] for t in sub.trajectories])
    assert torch.equal(dc.expert_states(sub), torch.from_numpy(want))


def test_pwil_refuses_to_subsample_a_subsample(demos):
    sub = data.subsample(demos, seed=0)
    with pytest.raises(LearnerInputError, match="subsampling=1"):
        pwil.expert_atoms(sub, pwil.PWILConfig(), seed=0)
    atoms, mean, _ = pwil.expert_atoms(sub, pwil.PWILConfig(subsampling=1), seed=0)
    obs, act = bc.pairs(sub)
    assert len(atoms) == len(obs)
    np.testing.assert_allclose(mean, torch.cat([obs, act], -1).double().mean(0).numpy())


def test_whole_episode_readers_are_explicit_and_bad_uses_are_refused(demos, tmp_path):
    sub = data.subsample(demos, seed=0)
    with pytest.raises(ValueError, match="subsampled already"):
        data.subsample(sub)
    with pytest.raises(ValueError, match="every"):
        data.subsample(demos, every=0)
    with pytest.raises(ValueError, match="subsampled demonstrations"):
        data.save_demos(list(sub.trajectories), tmp_path / "x.npz")
    config = bc.BCConfig(epochs=1, val_fraction=0.0, stop_on_others=True)
    with pytest.raises(LearnerInputError, match="stop_on_others"):
        bc.train("reacher1", sub, config, progress=False)
    t = demos.trajectories[0]
    for kept in ([3, 2], [0, len(t)], [], np.array([0.0, 1.0])):
        with pytest.raises(TrajectoryError, match="kept"):
            t.__class__(**{**{k: getattr(t, k) for k in ("task", "observations", "actions",
                                                          "rewards", "mode_features",
                                                          "initial_state", "seed", "mode")},
                           "kept": np.asarray(kept)})


def test_the_evaluation_reference_is_always_the_whole_episodes(demos):
    sub = data.subsample(demos, seed=0)
    episodes = demos.trajectories[:2]
    a = evaluate.measure("reacher1", episodes, sub, emd_n_max=500)
    b = evaluate.measure("reacher1", episodes, demos, emd_n_max=500)
    assert {k: a[k] for k in ("emd", "kl", "rkl")} == {k: b[k] for k in ("emd", "kl", "rkl")}
