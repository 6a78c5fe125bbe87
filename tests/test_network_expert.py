"""The network experts of walker, ant and humanoid (experts.network): DAgger distillation
against its teacher, the expert files the library loads, the planner kept as a variant, and
the command's refusals. (Whether SAC reaches the floors is what the stored experts' records
show: ``data/experts/TASK.json``, checked in tests/test_floors.py.)"""

import dataclasses
import json

import numpy as np
import pytest
import torch

from dc_lesson import cli, data
from dc_lesson.experts import DEFAULT_EXPERT, VARIANTS, load_expert, network, sac, trained
from dc_lesson.nn.policies import GaussianPolicy

TINY = dataclasses.replace(network.DISTIL, rounds=2, episodes_per_round=2, epochs=15,
                           hidden=(16,), eval_episodes=1)


def _teacher(task="reacher1", seed=0):
    from dc_lesson import tasks
    torch.manual_seed(seed)
    spec = tasks.SPECS[task]
    return sac.Actor(spec.obs_dim, spec.act_dim, (16,), -5.0, 2.0).eval()


def test_dagger_fits_the_teacher_and_repeats_itself():
    torch.set_num_threads(1)
    teacher = _teacher()
    student, log = network.distil("reacher1", teacher, TINY, progress=None)
    again, _ = network.distil("reacher1", teacher, TINY, progress=None)
    assert isinstance(student, GaussianPolicy)   # the learners' own class
    for a, b in zip(student.state_dict().values(), again.state_dict().values()):
        assert torch.equal(a, b)                 # one seed, the same student
    # every labelled state is kept: round r holds r + 1 rounds of episodes
    from dc_lesson import tasks
    T = tasks.spec("reacher1").horizon
    assert [row["states"] for row in log] == [2 * T * (r + 1) for r in range(TINY.rounds)]
    assert [row["rolled_out_by"] for row in log] == ["teacher", "student"]
    # the fit is a fit: on fresh states, the student is far closer to the teacher's action
    # than an untrained network of the same shape (a broken loss or label leaves it there)
    from dc_lesson.data import rollout
    obs = np.concatenate([t.observations for t in rollout.collect(
        "reacher1", teacher.act_numpy, 2, seed=77, progress=False)])
    target = teacher.act_numpy(obs)
    fresh = GaussianPolicy(student.obs_dim, student.act_dim, TINY.hidden, norm_obs=True)
    fresh.update_obs_norm(torch.as_tensor(obs))
    with torch.no_grad():
        err = float(((student(torch.as_tensor(obs)).numpy() - target) ** 2).mean())
        base = float(((fresh(torch.as_tensor(obs)).numpy() - target) ** 2).mean())
    assert err < 0.2 * base, (err, base)


def test_each_task_has_its_default_expert_and_the_other_as_its_variant():
    from dc_lesson.experts import DEFAULT_EXPERT, floors
    assert set(DEFAULT_EXPERT) == set(network.SAC_RECIPES)
    for task, kind in DEFAULT_EXPERT.items():
        other = "planner" if kind == "network" else "network"
        assert VARIANTS[task] == (other,)
        for variant, expect in ((None, kind), (other, other)):
            if expect == "network" and not network.paths(task)["policy"].exists():
                continue   # not trained yet (the note says which)
            policy, info = load_expert(task, variant)
            if expect == "planner":
                assert info["kind"] == "planner"
                continue
            assert info["name"] == "SAC, distilled by DAgger" and info["kind"] == "trained"
            net = trained.load_unit(task)
            assert isinstance(net, GaussianPolicy)
            # a network is the default only where it meets the task's floor
            assert (net.meta["student_return"]["mean"] >= floors.FLOORS[task]) == \
                (kind == "network")
    with pytest.raises(ValueError, match="no expert variant 'planner'"):
        load_expert("hopper", "planner")


def test_the_planner_demonstrations_stay_under_their_variant():
    from dc_lesson.experts import DEFAULT_EXPERT
    for task in [t for t, kind in DEFAULT_EXPERT.items() if kind == "network"]:
        assert data.manifest_entry(task)["expert"]["name"] == "SAC, distilled by DAgger"
        entry = data.manifest_entry(task, variant="planner")
        assert entry["expert"]["kind"] == "planner" and entry["variant"] == "planner"
        assert entry["file"] == f"{task}-planner.npz"
        assert "--variant planner" in entry["command"]


def test_the_stored_table3_grid_keeps_the_demonstrations_it_ran_on():
    from dc_lesson.experiments.studies import table3
    for task, variant in table3.DEMO_VARIANT.items():
        assert not table3.fresh_reference(task)          # it ran on the planner's
        assert len(table3.demos_of(task, 4)) == 4
        assert data.manifest_entry(task, variant=variant)["expert"]["kind"] == "planner"


def test_the_command_refuses_what_does_not_apply(capsys):
    assert cli.main(["expert", "train", "--task", "walker", "--steps", "10"]) != 0
    err = capsys.readouterr().err
    assert "SAC + distillation" in err and "--steps" in err
    assert cli.main(["expert", "train", "--task", "hopper", "--hours", "1"]) != 0
    assert "--hours applies to the network experts" in capsys.readouterr().err
    assert cli.main(["expert", "eval", "--task", "walker", "--hours", "1"]) != 0
    assert "apply to expert train" in capsys.readouterr().err


def test_a_missing_actor_names_the_command(tmp_path):
    with pytest.raises(FileNotFoundError, match="dc-lesson expert train --task ant"):
        network.load_sac_actor("ant", directory=tmp_path)
    with pytest.raises(ValueError, match="no SAC recipe for 'hopper'"):
        network.train_sac("hopper", directory=tmp_path)


def test_the_recipes_are_recorded_with_the_expert():
    for task in network.SAC_RECIPES:
        meta_path = network.paths(task)["meta"]
        if not meta_path.exists():
            continue
        meta = json.loads(meta_path.read_text())
        recipe = sac.json_config(network.SAC_RECIPES[task])
        # fields added to SACConfig since a run keep that run's behaviour at their defaults
        if {**sac.json_config(sac.SACConfig()), **meta["sac_config"]} != recipe:
            # a student distilled from a former recipe (the humanoid's 500k-step run) may stay
            # only as a variant, while the current recipe's run is under way and recorded
            assert DEFAULT_EXPERT[task] != "network", task
            sac_meta = json.loads(network.paths(task)["sac_meta"].read_text())
            assert sac_meta["config"] == recipe and not sac_meta["done"], task
            continue
        assert meta["distil_config"] == json.loads(json.dumps(
            dataclasses.asdict(network.DISTIL)))
        assert meta["learning_curve"] and meta["dagger"]


def test_the_humanoids_first_sac_run_is_kept_for_its_curve():
    from dc_lesson.experts import floors
    meta = json.loads(network.FIRST_HUMANOID_RUN.read_text())
    assert "humanoid-fall" in str(meta["sac_config"]) and meta["steps"] == 500_000
    assert max(r["episode_return"] for r in meta["learning_curve"]) < floors.FLOORS["humanoid"]


def test_sac_demonstrations_are_named_by_their_expert():
    """The humanoid's SAC samples the planner's demonstrations: the ``planner`` variant since
    the network became the default expert (the unnamed set before), never the network's own."""
    demos = network.sac_demonstrations("humanoid")
    assert len(demos) == 25 and all(t.task == "humanoid" for t in demos)
    planner = data.load_demos("humanoid", variant="planner").trajectories
    assert all(np.array_equal(a.actions, b.actions) for a, b in zip(demos, planner))
    assert data.manifest_entry("humanoid", variant="planner")["expert"]["kind"] == "planner"
    assert data.manifest_entry("humanoid")["expert"]["kind"] != "planner"
    assert network.sac_demonstrations("walker") is None   # no demo_fraction in its recipe
