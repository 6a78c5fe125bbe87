"""Hostile manifests and bad arguments to load_demos get clear errors (issue 19): no read
outside the demos folder, no hang on a device or FIFO, no deep TypeError."""

import json
import os
import shutil

import numpy as np
import pytest

from dc_lesson import data
from dc_lesson.data import DemoError, load_demos, store


@pytest.fixture
def demos_dir(tmp_path):
    """A copy of the cartpole demonstrations and a manifest listing only them."""
    d = tmp_path / "demos"
    d.mkdir()
    shutil.copy(store.DEMOS_DIR / "cartpole.npz", d / "cartpole.npz")
    manifest = json.loads((store.DEMOS_DIR / "manifest.json").read_text())
    manifest["tasks"] = {"cartpole": manifest["tasks"]["cartpole"]}
    (d / "manifest.json").write_text(json.dumps(manifest))
    return d


def _point_at(d, name):
    manifest = json.loads((d / "manifest.json").read_text())
    manifest["tasks"]["cartpole"]["file"] = name
    (d / "manifest.json").write_text(json.dumps(manifest))


def test_the_copy_loads(demos_dir):
    assert len(load_demos("cartpole", directory=demos_dir).trajectories) > 1


@pytest.mark.parametrize("name, message", [
    ("/etc/passwd", "must be a plain name"),
    ("../outside.npz", "must be a plain name"),
    ("sub/../../outside.npz", "must be a plain name"),
    ("/dev/zero", "must be a plain name"),
    ("", "names no file"),
    (7, "names no file"),
])
def test_names_outside_the_folder_are_refused(demos_dir, name, message):
    (demos_dir.parent / "outside.npz").write_bytes(b"secret")
    _point_at(demos_dir, name)
    with pytest.raises(DemoError, match=message) as e:
        load_demos("cartpole", directory=demos_dir)
    assert "dc-lesson demos --task cartpole" in str(e.value)


def test_a_link_out_of_the_folder_is_refused(demos_dir):
    (demos_dir.parent / "outside.npz").write_bytes(b"secret")
    os.symlink(demos_dir.parent / "outside.npz", demos_dir / "link.npz")
    _point_at(demos_dir, "link.npz")
    with pytest.raises(DemoError, match="leads out of the demos folder"):
        load_demos("cartpole", directory=demos_dir)


def test_a_link_to_a_device_is_refused_without_reading(demos_dir):
    os.symlink("/dev/zero", demos_dir / "zero.npz")
    _point_at(demos_dir, "zero.npz")
    with pytest.raises(DemoError):   # out of the folder, and not a regular file
        load_demos("cartpole", directory=demos_dir)


def test_a_fifo_is_refused_without_blocking(demos_dir):
    os.mkfifo(demos_dir / "fifo.npz")
    _point_at(demos_dir, "fifo.npz")
    with pytest.raises(DemoError, match="not a regular file"):
        load_demos("cartpole", directory=demos_dir)
    with pytest.raises(DemoError, match="not a regular file"):
        data.read_demo_file(demos_dir / "fifo.npz", "cartpole")


def test_a_folder_and_a_bad_manifest_are_refused(demos_dir):
    (demos_dir / "dir.npz").mkdir()
    _point_at(demos_dir, "dir.npz")
    with pytest.raises(DemoError, match="not a regular file"):
        load_demos("cartpole", directory=demos_dir)
    (demos_dir / "manifest.json").write_text(json.dumps({"tasks": ["cartpole"]}))
    with pytest.raises(DemoError, match="not a demonstration manifest"):
        load_demos("cartpole", directory=demos_dir)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"n_trajectories": 2.5}, TypeError, "n_trajectories must be a whole number"),
    ({"n_trajectories": "3"}, TypeError, "n_trajectories must be a whole number"),
    ({"n_trajectories": True}, TypeError, "n_trajectories must be a whole number"),
    ({"n_trajectories": 0}, ValueError, "n_trajectories must be at least 1"),
    ({"n_trajectories": 10_000}, ValueError, "asked for 10000"),
    ({"n_trajectories": 2, "seed": -1}, ValueError, "seed must be at least 0"),
    ({"n_trajectories": 2, "seed": 1.5}, TypeError, "seed must be a whole number"),
    ({"directory": 3}, TypeError, "directory must be a path"),
])
def test_bad_arguments_get_clear_errors(kwargs, error, message):
    with pytest.raises(error, match=message):
        load_demos("cartpole", **kwargs)


def test_numpy_integers_are_whole_numbers():
    a = load_demos("cartpole", n_trajectories=np.int64(2), seed=np.int64(1))
    b = load_demos("cartpole", n_trajectories=2, seed=1)
    assert [t.seed for t in a.trajectories] == [t.seed for t in b.trajectories]
