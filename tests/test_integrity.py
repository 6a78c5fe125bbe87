"""Model files carry a sha256 checked before loading; killed saves leave nothing behind for
long; result JSON is standard.  (Issue 19: 238 of 300 single-bit flips in a policy file used
to load silently with changed weights.)"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

from dc_lesson import storage
from dc_lesson.experts import trained
from dc_lesson.nn import checkpoint
from dc_lesson.nn.checkpoint import ModelFileError, atomic_torch_save, load_checked
from dc_lesson.nn.policies import GaussianPolicy, load_policy, save_policy

EXPERTS = storage.DATA / "experts"


@pytest.mark.parametrize("path", sorted(EXPERTS.glob("*.pt")) + sorted(EXPERTS.glob("checkpoints/*.ckpt")),
                         ids=lambda p: p.name)
def test_every_committed_model_file_matches_its_sidecar(path):
    assert storage.sha256(path) in checkpoint.read_checksums(path)


@pytest.mark.parametrize("bit", [8 * 100 + 3, 8 * 9000 + 5, 8 * 20000 + 0])
def test_a_flipped_bit_in_an_expert_is_refused_with_the_file_and_fix(tmp_path, bit):
    for name in ("hopper.pt", "hopper.pt.sha256"):
        shutil.copy(EXPERTS / name, tmp_path / name)
    copy = tmp_path / "hopper.pt"
    assert load_policy(copy).config()["obs_dim"] == 11   # the intact copy loads (Gym's hopper)
    data = bytearray(copy.read_bytes())
    data[bit // 8] ^= 1 << (bit % 8)
    copy.write_bytes(bytes(data))
    with pytest.raises(ModelFileError) as e:
        trained.load_unit("hopper", directory=tmp_path)
    msg = str(e.value)
    assert str(copy) in msg and "does not match its sha256" in msg
    assert "dc-lesson expert train --task hopper" in msg and "git checkout" in msg


def test_every_one_of_300_single_bit_flips_is_refused(tmp_path):
    """The issue's measurement: 238 of 300 flips used to load silently with changed weights."""
    for name in ("hopper.pt", "hopper.pt.sha256"):
        shutil.copy(EXPERTS / name, tmp_path / name)
    copy = tmp_path / "hopper.pt"
    good = copy.read_bytes()
    rng = np.random.default_rng(0)
    for bit in rng.choice(8 * len(good), 300, replace=False):
        data = bytearray(good)
        data[bit // 8] ^= 1 << (bit % 8)
        copy.write_bytes(bytes(data))
        with pytest.raises(ModelFileError, match="does not match its sha256"):
            load_policy(copy)


def test_a_file_without_sidecar_is_refused(tmp_path):
    path = save_policy(GaussianPolicy(3, 1), tmp_path / "p.pt")
    checkpoint.checksum_path(path).unlink()
    with pytest.raises(ModelFileError, match="p.pt has no checksum file p.pt.sha256"):
        load_policy(path)


class _Evil:
    def __reduce__(self):
        return (os.system, ("echo pwned",))


def test_a_malicious_file_is_refused_without_torchs_advice(tmp_path):
    path = tmp_path / "evil.pt"
    torch.save({"format": "dc_lesson.policy", "version": 1, "x": _Evil()}, path)
    checkpoint.write_checksum(path)   # even with a valid sidecar: weights_only refuses it
    with pytest.raises(ModelFileError) as e:
        load_policy(path, fix="rerun it")
    msg = str(e.value)
    assert str(path) in msg and "refused without running them" in msg and "rerun it" in msg
    assert "weights_only" not in msg and "WeightsUnpickler" not in msg
    assert "\n" not in msg


def test_replacing_a_file_keeps_it_loadable_at_every_step(tmp_path, monkeypatch):
    """Between the data's rename and the sidecar's, the sidecar accepts old and new."""
    path = tmp_path / "run.ckpt"
    atomic_torch_save({"format": "f", "version": 1, "x": torch.zeros(3)}, path)
    seen = []
    real_replace = os.replace

    def spying_replace(src, dst):
        real_replace(src, dst)
        if pathlib.Path(dst) == path:   # the data was just renamed; the sidecar not yet final
            seen.append(load_checked(path, "f", 1, "run")["x"].clone())
    monkeypatch.setattr(os, "replace", spying_replace)
    atomic_torch_save({"format": "f", "version": 1, "x": torch.ones(3)}, path)
    assert len(seen) == 1 and torch.equal(seen[0], torch.ones(3))
    assert len(checkpoint.read_checksums(path)) == 1   # finally only the new digest
    assert torch.equal(load_checked(path, "f", 1, "run")["x"], torch.ones(3))


def test_train_unit_rewrites_a_damaged_policy_and_restart_discards_the_checkpoint(tmp_path):
    # A damaged finished policy is not taken as trained.
    for name in ("hopper.pt", "hopper.pt.sha256", "hopper.json"):
        shutil.copy(EXPERTS / name, tmp_path / name)
    (tmp_path / "hopper.pt").write_bytes(b"damaged")
    with pytest.raises(ModelFileError):
        trained.load_unit("hopper", directory=tmp_path)
    # The config-mismatch refusal names --restart; restart=True discards the checkpoint.
    (tmp_path / "checkpoints").mkdir()
    for name in ("hopper.ckpt", "hopper.ckpt.sha256"):
        shutil.copy(EXPERTS / "checkpoints" / name, tmp_path / "checkpoints" / name)
    with pytest.raises(ModelFileError, match="another configuration.*--restart"):
        trained.train_unit("hopper", total_steps=4096, directory=tmp_path, progress=False)
    with pytest.raises(ValueError, match="total_steps must be a positive integer"):
        trained.train_unit("hopper", total_steps=0, directory=tmp_path, progress=False)


# -- temporary files of killed saves -------------------------------------------------------------

def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_stale_temporaries_are_removed_by_the_next_save(tmp_path):
    dead = tmp_path / f".policy.pt.{_dead_pid()}.0123abcd.tmp"           # writer is gone
    old = tmp_path / f".policy.pt.{os.getppid()}.89abcdef.tmp"           # alive but 2 h old
    live = tmp_path / f".policy.pt.{os.getppid()}.00000000.tmp"          # alive and fresh
    legacy = tmp_path / "result.json.k3j4_x9a.tmp"                       # old mkstemp name
    fresh_legacy = tmp_path / "other.json.abcdefgh.tmp"
    mine = tmp_path / "notes.tmp"                                        # not our pattern
    for p in (dead, old, live, legacy, fresh_legacy, mine):
        p.write_bytes(b"x" * 100)
    two_hours_ago = time.time() - 7200
    for p in (old, legacy, mine):
        os.utime(p, (two_hours_ago, two_hours_ago))
    save_policy(GaussianPolicy(3, 1), tmp_path / "p.pt")
    left = {p.name for p in tmp_path.iterdir()}
    assert left == {"p.pt", "p.pt.sha256", live.name, fresh_legacy.name, mine.name}


def test_a_killed_save_leaves_a_temporary_that_the_next_save_removes(tmp_path):
    code = ("import os, torch\nfrom dc_lesson.nn.checkpoint import atomic_torch_save\n"
            "class Boom:\n  def __reduce__(self): os._exit(9)\n"   # dies mid-write
            f"atomic_torch_save({{'x': torch.zeros(10000), 'y': Boom()}}, {str(tmp_path / 'a.pt')!r})\n")
    env = {**os.environ, "PYTHONPATH": str(pathlib.Path(storage.__file__).parent.parent)}
    assert subprocess.run([sys.executable, "-c", code], env=env).returncode == 9
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]   # one was left
    atomic_torch_save({"x": torch.zeros(2)}, tmp_path / "b.pt")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.pt", "b.pt.sha256"]


# -- result JSON ---------------------------------------------------------------------------------

def test_result_json_is_standard_with_nan_as_null(tmp_path):
    path = storage.write_result(tmp_path / "r.json",
                                {"a": float("nan"), "b": [1.0, float("inf"), np.float32(2.5)],
                                 "c": {"d": np.float64("-inf"), "e": np.int64(3)},
                                 "f": np.array([0.5, np.nan])}, command="test", seeds=[0])
    text = path.read_text()
    assert "NaN" not in text and "Infinity" not in text
    rec = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard {c}"))
    assert rec["a"] is None and rec["b"] == [1.0, None, 2.5]
    assert rec["c"] == {"d": None, "e": 3} and rec["f"] == [0.5, None]


# -- issue 42: saves killed twice, files copied over others, cell records -----------------------

def test_two_saves_killed_before_their_rename_leave_the_intact_file_loadable(tmp_path,
                                                                            monkeypatch):
    """The sidecar used to keep the first killed save's digest as "the old one", so after a
    second kill it no longer accepted the intact file on disk."""
    path = tmp_path / "run.ckpt"
    atomic_torch_save({"format": "f", "version": 1, "x": torch.zeros(3)}, path)
    real_replace = os.replace

    def killed_before_rename(src, dst):
        if pathlib.Path(dst) == path:
            raise KeyboardInterrupt   # the process dies before the data's rename
        real_replace(src, dst)
    monkeypatch.setattr(os, "replace", killed_before_rename)
    for value in (1.0, 2.0):
        with pytest.raises(KeyboardInterrupt):
            atomic_torch_save({"format": "f", "version": 1, "x": torch.full((3,), value)}, path)
    monkeypatch.setattr(os, "replace", real_replace)
    assert torch.equal(load_checked(path, "f", 1, "run")["x"], torch.zeros(3))


def test_a_units_files_copied_over_another_units_are_refused(tmp_path):
    for name in ("hopper.pt", "hopper.pt.sha256"):
        shutil.copy(EXPERTS / name, tmp_path / name.replace("hopper", "walker"))
    with pytest.raises(ModelFileError, match="walker.pt has no checksum file walker.pt.sha256 "
                                             "naming it.*copied from another file"):
        load_policy(tmp_path / "walker.pt")


from dc_lesson import cli   # noqa: E402
from dc_lesson.experiments import cells   # noqa: E402

CELLS = storage.DATA / "results" / "cells"


def test_every_committed_cell_record_carries_digests_that_match():
    paths = sorted(CELLS.glob("*/*/*.json"))
    assert len(paths) > 1000
    for p in paths:
        record = cells.read_record(p)
        assert cells.DIGEST in record, f"{p} has no digest: run dc-lesson seal-cells"
        if record["features_file"]:
            assert cells.FEATURES_DIGEST in record
            cells.read_features(p, record)


@pytest.fixture
def study_copy(tmp_path, monkeypatch):
    """A data folder holding a copy of bc_demos' cells (and the references they read)."""
    for study in ("bc_demos", "reference"):
        shutil.copytree(CELLS / study, tmp_path / "results" / "cells" / study)
    for sub in ("demos", "experts"):
        (tmp_path / sub).symlink_to(storage.DATA / sub)
    monkeypatch.setenv(storage.DATA_ENV, str(tmp_path))
    return tmp_path / "results" / "cells" / "bc_demos"


def _edit(path, old: str, new: str):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def test_a_hand_edited_result_is_refused_by_aggregate_naming_the_file_and_fix(study_copy,
                                                                              capsys):
    assert cli.main(["aggregate", "bc_demos", "--budget", "lesson"]) == 0   # the intact copy
    out = study_copy.parent.parent / "bc_demos.json"
    before = out.read_bytes()
    path = sorted(study_copy.glob("*/bc__*.json"))[0]
    value = json.loads(path.read_text())["result"]["measures"]["scaled_return"]
    _edit(path, f'"scaled_return": {value}', f'"scaled_return": {value + 0.05}')
    capsys.readouterr()
    assert cli.main(["aggregate", "bc_demos", "--budget", "lesson"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "does not match its sha256" in err
    assert f"git checkout -- {path}" in err and "dc-lesson sweep bc_demos" in err
    assert "Traceback" not in err and out.read_bytes() == before


@pytest.mark.parametrize("replacement, kind", [("true", "bool"), ('"0.7606"', "str")])
def test_a_wrong_type_where_a_measure_belongs_is_refused_naming_the_field(study_copy, replacement,
                                                                         kind):
    path = sorted(study_copy.glob("*/bc__*.json"))[0]
    record = json.loads(path.read_text())
    record["result"]["measures"]["scaled_return"] = json.loads(replacement)
    for sealed in (True, False):   # with its digest, and as a record from before digests
        if not sealed:
            del record[cells.DIGEST]
        path.write_text(json.dumps(record, indent=1))
        with pytest.raises(cells.CellError) as e:
            cells.read_record(path)
        assert str(path) in str(e.value) and "result.measures.scaled_return" in str(e.value)
        assert f"({kind}) where a number" in str(e.value) and "git checkout" in str(e.value)


def test_a_bit_flip_in_a_record_or_its_features_is_refused(study_copy):
    path = next(p for p in sorted(study_copy.parent.glob("*/*/*.json"))
                if json.loads(p.read_text())["features_file"])
    features = cells.features_path(path)
    good = features.read_bytes()
    data = bytearray(good)
    data[len(data) // 2] ^= 4
    features.write_bytes(bytes(data))
    with pytest.raises(cells.CellError, match="features file .* does not match the sha256"):
        cells.read_features(path)
    features.write_bytes(good)
    text = path.read_text()
    i = next(i for i, c in enumerate(text) if c.isdigit() and i > len(text) // 3)
    path.write_text(text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1:])
    with pytest.raises(cells.CellError, match="does not match"):
        cells.read_record(path)


def test_seal_adds_digests_once_and_never_seals_a_damaged_record(study_copy):
    paths = sorted(study_copy.glob("*/*.json"))
    for p in paths[:2]:
        record = json.loads(p.read_text())
        record.pop(cells.DIGEST)
        record.pop(cells.FEATURES_DIGEST, None)
        p.write_text(json.dumps(record, indent=1) + "\n")
    sealed, already = cells.seal()
    assert sealed == 2 and already == len(list(study_copy.parent.glob("*/*/*.json"))) - 2
    assert all(cells.DIGEST in cells.read_record(p) for p in paths[:2])
    record = json.loads(paths[0].read_text())
    record.pop(cells.DIGEST)
    record["result"]["measures"]["scaled_return"] = True
    paths[0].write_text(json.dumps(record, indent=1) + "\n")
    with pytest.raises(cells.CellError, match="where a number"):
        cells.seal()
    assert cells.DIGEST not in json.loads(paths[0].read_text())


def test_a_yes_no_flag_may_be_a_bool_where_it_is_named_and_nowhere_else(tmp_path):
    path = tmp_path / "cell.json"
    ok = {"result": {"match": {"target": 0.9, "matched": False}}}
    cells._numbers_only(ok["result"], "result", path)          # the named flag: accepted
    bad = {"result": {"match": {"target": True, "matched": False}}}
    with pytest.raises(cells.CellError, match=r"result.match.target is True \(bool\)"):
        cells._numbers_only(bad["result"], "result", path)
    with pytest.raises(cells.CellError, match=r"matched is 'no' \(str\)"):
        cells._numbers_only({"matched": "no"}, "result", path)
