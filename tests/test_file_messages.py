"""A damaged or foreign file is refused by a message that names it (issue 42: the hostile tour
found messages about files that named none: json's "Expecting value: line 1 column 1", a
codec's "can't decode byte 0xff", a bare KeyError 'log')."""

import json

import pytest

from dc_lesson import data, storage
from dc_lesson.data import store
from dc_lesson.experts import floors, network, sac, trained
from dc_lesson.nn.checkpoint import ModelFileError, atomic_torch_save


def test_text_that_is_not_utf8_or_json_names_the_file(tmp_path):
    p = tmp_path / "record.json"
    p.write_bytes(b"\xff\xfe{}")
    with pytest.raises(storage.UnreadableFileError, match=f"result file {p} is not UTF-8"):
        storage.read_text(p, "result file", "regenerate it")
    p.write_text("{not json")
    with pytest.raises(storage.UnreadableFileError,
                       match=f"result file {p} is not valid JSON .*; regenerate it"):
        storage.read_json(p, "result file", "regenerate it")
    with pytest.raises(ValueError, match=f"result file {p} is not valid JSON"):
        storage.read_result(p)


def test_a_manifest_without_the_task_or_its_digest_is_named(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"tasks": {"cartpole": {"file": "c.npz"}}}))
    with pytest.raises(data.DemoError, match=f"the manifest {tmp_path}/manifest.json has no "
                                             "demonstrations 'reacher4'"):
        data.load_demos("reacher4", directory=tmp_path)
    (tmp_path / "c.npz").write_bytes(b"x")
    with pytest.raises(data.DemoError, match=f"in {tmp_path}/manifest.json has no sha256"):
        data.load_demos("cartpole", directory=tmp_path)


def test_saving_demonstrations_of_two_tasks_names_the_file(tmp_path):
    a = data.load_demos("cartpole", n_trajectories=1).trajectories
    b = data.load_demos("reacher1", n_trajectories=1).trajectories
    with pytest.raises(ValueError, match=f"for {tmp_path}/x.npz are of .'cartpole', 'reacher1'"):
        store.save_demos(a + b, tmp_path / "x.npz")
    with pytest.raises(ValueError, match=f"no trajectories to save to {tmp_path}/x.npz"):
        store.save_demos([], tmp_path / "x.npz")


@pytest.mark.parametrize("content, says", [
    ("{\"task\": \"hopper\"", "is not valid JSON"),
    (json.dumps({"task": "hopper", "learning_curve": [{"steps": 1}]}), "lacks 'training_seconds'"),
    (json.dumps({"task": "hopper", "training_seconds": 1, "learning_curve": [{"steps": 1}]}),
     "row without 'episode_return'"),
    (json.dumps([1, 2]), "holds list, not a JSON object"),
])
def test_a_damaged_training_record_names_the_file(tmp_path, content, says):
    (tmp_path / "hopper.json").write_text(content)
    with pytest.raises(storage.UnreadableFileError, match=says) as e:
        trained.learning_curve("hopper", directory=tmp_path)
    assert f"training record {tmp_path}/hopper.json" in str(e.value)
    assert "git checkout -- data/experts/hopper.json" in str(e.value)


def test_a_sac_record_without_its_log_names_the_file(tmp_path):
    path = network.paths("walker", tmp_path)["sac_meta"]
    path.write_text(json.dumps({"task": "walker", "training_seconds": 1.0, "done": True,
                                "config": {"total_steps": 10}}))
    with pytest.raises(storage.UnreadableFileError, match=f"SAC record {path} lacks 'log'.*"
                                                          "dc-lesson expert train --task walker"):
        network.sac_curve("walker", directory=tmp_path)


def test_a_sac_actor_whose_checksum_holds_but_whose_config_does_not_names_the_file(tmp_path):
    p = network.paths("ant", tmp_path)["actor"]
    atomic_torch_save({"format": network.ACTOR_FORMAT, "version": network.ACTOR_VERSION,
                       "config": "{}", "state_dict": {}}, p)
    with pytest.raises(ModelFileError, match=f"SAC actor {p} holds no usable configuration"):
        network.load_sac_actor("ant", directory=tmp_path)


def test_a_sac_checkpoint_missing_a_part_names_the_file(tmp_path):
    cfg = sac.SACConfig(total_steps=2000, checkpoint_every=1000, log_every=1000)
    ckpt = tmp_path / "walker.sac"
    atomic_torch_save({"format": sac.CHECKPOINT_FORMAT, "version": sac.CHECKPOINT_VERSION,
                       "config": sac.json_config(cfg)}, ckpt)   # no networks, no buffer
    with pytest.raises(ModelFileError, match=f"SAC checkpoint {ckpt} is inconsistent "
                                             r"\(KeyError: 'actor'\); delete"):
        sac.train("walker", cfg, checkpoint=ckpt)


def test_a_damaged_clonable_result_names_the_file(tmp_path):
    (tmp_path / "clonable.json").write_text(json.dumps({"table": [{"demonstrations": "hopper",
                                                                    "task": "hopper"}]}))
    with pytest.raises(storage.UnreadableFileError,
                       match=f"result file {tmp_path}/clonable.json has a table row without"):
        floors.bc_from_25(tmp_path)
