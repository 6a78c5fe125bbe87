"""Every learner of the registry, through the one interface, at the smoke budget."""

import copy
import dataclasses

import pytest
import torch

from dc_lesson import algorithms, budget, data
from dc_lesson.algorithms import TrainResult
from dc_lesson.nn.policies import GaussianPolicy

TASK = "reacher1"
SMOKE = budget.get("smoke")


@pytest.fixture(scope="module")
def demos():
    return data.load_demos(TASK, n_trajectories=4)


def _small(name: str, seed: int):
    """The smoke preset, cut to a few iterations so the test stays quick."""
    config = algorithms.get(name).preset(SMOKE, seed)
    if name == "bc":
        return dataclasses.replace(config, epochs=2)
    if name == "dc":
        return dataclasses.replace(config, loops=1, iterations=2)
    return config


def _run(name, demos, seed=0, policy=None):
    algo = algorithms.get(name)
    torch.manual_seed(123)   # a learner must not depend on the global RNG
    return algo.train(TASK, demos if algo.uses_demos else None, _small(name, seed),
                      policy=copy.deepcopy(policy), progress=False)


def _vector(policy) -> torch.Tensor:
    return torch.cat([p.detach().flatten() for p in policy.state_dict().values()])


@pytest.mark.parametrize("name", list(algorithms.ALGORITHMS))
def test_every_learner_trains_through_the_registry(name, demos):
    algo = algorithms.get(name)
    assert algo.name == name and dataclasses.is_dataclass(algo.config)
    config = algo.preset(SMOKE, 0)
    assert isinstance(config, algo.config)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.seed = 1                      # configs are frozen
    result = _run(name, demos)
    assert isinstance(result, TrainResult) and result.algorithm == name
    assert isinstance(result.policy, GaussianPolicy)
    assert result.log and all(isinstance(r, dict) for r in result.log)
    expected_models = {"bc": set(), "ppo": {"value"}, "gail": {"discriminator", "value"},
                       "dc": {"flow", "value"}, "dril": {"ensemble", "value"},
                       "pwil": {"value"}, "ndi": {"flow", "value"},
                       "gpril": {"state_flow", "action_flow"}}[name]
    assert set(result.models) == expected_models
    # same seed, same parameters; another seed, others
    again = _run(name, demos)
    assert torch.equal(_vector(result.policy), _vector(again.policy))
    other = _run(name, demos, seed=1)
    assert not torch.equal(_vector(result.policy), _vector(other.policy))


@pytest.mark.parametrize("name", ["gail", "dc", "dril", "pwil", "ndi", "gpril"])
def test_learners_refuse_a_policy_or_demos_of_another_task(name, demos):
    with pytest.raises(algorithms.LearnerInputError, match="policy is built for"):
        _run(name, demos, policy=GaussianPolicy(5, 1))
    with pytest.raises(algorithms.LearnerInputError, match="demonstrations are of"):
        algorithms.get(name).train("reacher2", demos, _small(name, 0), progress=False)


def test_unknown_learner_names_the_registered_ones():
    with pytest.raises(algorithms.UnknownAlgorithmError) as e:
        algorithms.get("gial")
    for name in algorithms.ALGORITHMS:
        assert name in str(e.value)


def test_bc_takes_no_start_and_no_checkpoint(demos, tmp_path):
    with pytest.raises(algorithms.LearnerInputError, match="from scratch"):
        algorithms.bc.train(TASK, demos, _small("bc", 0), checkpoint=tmp_path / "x")


def test_one_seed_splits_into_named_streams_that_grow_without_moving():
    """Every learner splits its seed with ``base.seed_streams``: distinct streams, the same
    for the same seed, and a stream added at the end moves none before it (which is why a
    learner with five streams and one with three agree on the first three)."""
    import inspect
    import re

    from dc_lesson.algorithms import base
    three = base.seed_streams(7, "init", "sample", "env")
    five = base.seed_streams(7, "init", "sample", "env", "disc", "expert")
    assert five[:3] == three and len(set(five)) == 5
    assert base.seed_streams(8, "init", "sample", "env") != three
    with pytest.raises(ValueError, match="distinct stream names"):
        base.seed_streams(7, "env", "env")
    # no learner draws its own split any more (one helper, one place to read it)
    for name in algorithms.ALGORITHMS:
        src = inspect.getsource(inspect.getmodule(algorithms.get(name).train))
        assert not re.search(r"SeedSequence\(\w+(\.seed)?\)\.generate_state", src), name
