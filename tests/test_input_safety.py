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


# -- issue 42: every reader refuses a FIFO or a device (one guard, storage.open_regular) --------

import contextlib
import signal

from dc_lesson import storage
from dc_lesson.experiments import cells, sweep
from dc_lesson.experts import demos as demos_module
from dc_lesson.nn import checkpoint


@contextlib.contextmanager
def _within(seconds=20):
    """Fails (instead of hanging the suite) if the block blocks, as a FIFO's read would."""
    def timeout(*_):
        raise AssertionError(f"blocked for {seconds} s")
    old = signal.signal(signal.SIGALRM, timeout)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _hostile(path, kind):
    """Replaces ``path`` with a FIFO or a link to /dev/zero."""
    if path.exists() or path.is_symlink():
        path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    else:
        os.symlink("/dev/zero", path)


KINDS = ["fifo", "zero"]
KIND_WORD = {"fifo": "FIFO", "zero": "device"}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("which", ["model", "sidecar"])
def test_a_model_file_or_its_sidecar_that_is_not_regular_is_refused(tmp_path, kind, which):
    path = tmp_path / "m.pt"
    checkpoint.atomic_torch_save({"format": "t", "version": 1}, path)
    _hostile(path if which == "model" else checkpoint.checksum_path(path), kind)
    with _within(), pytest.raises(checkpoint.ModelFileError, match=KIND_WORD[kind]) as e:
        checkpoint.load_checked(path, "t", 1, "test model", fix="rerun it")
    assert "not a regular file" in str(e.value) and "rerun it" in str(e.value)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("which", ["stamp", "episodes"])
def test_a_planner_partial_file_that_is_not_regular_is_refused(tmp_path, kind, which):
    partial = tmp_path / "ant-demos.npz"
    partial.write_bytes(b"x")
    stamp = partial.with_suffix(".json")
    stamp.write_text("{}")
    _hostile(stamp if which == "stamp" else partial, kind)
    with _within(), pytest.raises(storage.NotRegularFileError, match=KIND_WORD[kind]) as e:
        demos_module._resumable_episodes("ant", partial, stamp, "fp", 0)
    assert "dc-lesson demos --task ant" in str(e.value)


def _record(root):
    cell = cells.make_cell("demo", "bc", "reacher4", 4, 0, {"epochs": 3})
    return cell, cells.write_record(cell, {"score": 0.5}, {"f": np.zeros((2, 1))},
                                    cells.provenance(command="t", budget="smoke", threads=1,
                                                     wall_seconds=1.0, platform={}), root)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("which", ["record", "features"])
def test_a_cell_file_that_is_not_regular_is_refused(tmp_path, kind, which):
    cell, path = _record(tmp_path)
    _hostile(path if which == "record" else cells.features_path(path), kind)
    with _within(), pytest.raises(cells.CellError, match=KIND_WORD[kind]) as e:
        cells.load(cell, tmp_path)
    assert "git checkout" in str(e.value) and "dc-lesson sweep demo" in str(e.value)


def test_a_fifo_among_the_cells_hangs_neither_a_dry_run_nor_an_aggregate(tmp_path, capsys,
                                                                         monkeypatch):
    """The issue: one FIFO anywhere under results/cells hung every `sweep --dry-run` and
    `aggregate`.  A dry run skips it (it is no finished cell); reading it is an error."""
    from dc_lesson import budget, cli
    (tmp_path / "results" / "cells" / "table3" / "hopper").mkdir(parents=True)
    os.mkfifo(tmp_path / "results" / "cells" / "table3" / "hopper" / "x__n4__s0__0.json")
    monkeypatch.setenv(storage.DATA_ENV, str(tmp_path))
    with _within(60):
        assert sweep.measured_costs() == {}
        with pytest.raises(cells.CellError, match="FIFO"):
            cells.records("table3")
        assert cli.main(["aggregate", "bc_demos", "--budget", "smoke"]) == 2
    assert budget.current().name == "smoke"
    assert not (tmp_path / "results" / "bc_demos.json").exists()


@pytest.mark.parametrize("kind", KINDS)
def test_a_result_file_that_is_not_regular_is_refused(tmp_path, kind):
    _hostile(tmp_path / "r.json", kind)
    with _within(), pytest.raises(storage.NotRegularFileError, match="regenerate it"):
        storage.read_result(tmp_path / "r.json")
