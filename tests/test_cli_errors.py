"""Every dc-lesson command turns a bad value, a damaged file or an unwritable output into one
line naming the fault and the fix, exit status 2, no traceback, and before any compute
(issue 19: 23 inputs leaked tracebacks; sizes of 0 were silently replaced by defaults)."""

import os
import re
import pathlib
import shutil
import subprocess
import sys
import time

import pytest

import dc_lesson
from dc_lesson import cli
from dc_lesson.data import store
from dc_lesson.experts import trained

ROOT = pathlib.Path(dc_lesson.__file__).resolve().parent.parent   # the checkout


def _corrupt_copy(src_dir: pathlib.Path, dst_dir: pathlib.Path, name: str) -> None:
    """``dst_dir``: links to every file of ``src_dir`` but a copy of ``name`` with one bit
    flipped (its sha256 no longer matches the manifest's)."""
    dst_dir.mkdir(parents=True)
    for f in src_dir.iterdir():
        if f.is_file() and f.name != name:
            os.symlink(f, dst_dir / f.name)
    data = bytearray((src_dir / name).read_bytes())
    data[len(data) // 2] ^= 0x10
    (dst_dir / name).write_bytes(bytes(data))


@pytest.fixture
def corrupt_demos(tmp_path, monkeypatch):
    d = tmp_path / "demos"
    _corrupt_copy(store.DEMOS_DIR, d, "reacher4.npz")
    monkeypatch.setattr(store, "DEMOS_DIR", d)
    return d


@pytest.fixture
def expert_copy(tmp_path, monkeypatch):
    """The hopper's committed expert files in a folder of their own (nothing committed is
    touched); returns the folder."""
    d = tmp_path / "experts"
    (d / "checkpoints").mkdir(parents=True)
    for name in ("hopper.pt", "hopper.pt.sha256", "hopper.json"):
        shutil.copy(trained.EXPERTS_DIR / name, d / name)
    for name in ("hopper.ckpt", "hopper.ckpt.sha256"):
        shutil.copy(trained.EXPERTS_DIR / "checkpoints" / name, d / "checkpoints" / name)
    monkeypatch.setattr(trained, "EXPERTS_DIR", d)
    return d


def run(argv, capsys):
    """(exit status, stderr) of ``dc-lesson ARGV`` run in this process."""
    t0 = time.perf_counter()
    try:
        code = cli.main(argv)
    except SystemExit as e:   # argparse's own refusal of a bad value
        code = e.code
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < 30, "the refusal came after compute"
    return code, err


# (arguments, a fixture it needs or None, what the message must say)
CASES = [
    (["expert", "eval", "--task", "cartpole", "--episodes", "0"], None, "must be at least 1"),
    (["expert", "eval", "--task", "cartpole", "--episodes", "-3"], None, "must be at least 1"),
    (["expert", "eval", "--task", "cartpole", "--restart"], None, "apply to expert train"),
    (["expert", "train", "--task", "hopper", "--steps", "0"], None, "must be at least 1"),
    (["expert", "train", "--task", "hopper", "--steps", "4096"], "expert_copy",
     "another configuration.*--restart"),
    (["expert", "eval", "--task", "hopper"], "damaged_expert",
     "does not match its sha256.*dc-lesson expert train --task hopper"),
    (["demos", "--task", "cartpole", "--stage", "demos"], None, "has no planner expert"),
    (["demos", "--task", "cartpole", "--first", "3"], None, "--first applies to --stage eval"),
    (["tour", "--no-headline", "--out", "{tmp}/file.txt"], "a_file", "is a file"),
    (["tour"], "corrupt_demos", "reacher4.npz does not match its sha256"),
    (["train", "gail", "--task", "nope"], None, "nope"),
    (["train", "nope", "--task", "cartpole"], None, "unknown learner 'nope'"),
    (["train", "bc", "--task", "cartpole", "--demos", "0"], None, "must be at least 1"),
    (["train", "bc", "--task", "cartpole", "--demos", "100000"], None, "asked for 100000"),
    (["train", "ppo", "--task", "cartpole", "--demos", "3"], None, "leave out --demos"),
    (["train", "bc", "--task", "cartpole", "--save", "{tmp}/{nope}.pt"], None,
     "only {task} and {learner}"),
    (["train", "bc", "--task", "cartpole", "--save", "{tmp}"], None, "is a folder"),
    (["perf", "rollout", "--steps", "0"], None, "must be at least 1"),
    (["perf", "softflow", "--tasks", "cartpole"], None, "does not take --tasks"),
    (["perf", "learners", "--steps", "5"], None, "does not take --steps"),
    (["perf", "rollout", "--steps", "2.5"], None, "must be a whole number"),
    (["perf", "rollout", "--tasks", "reacher4", "--out", "{tmp}"], None, "is a folder"),
    (["train", "dc", "--task", "reacher4"], "corrupt_demos", "reacher4.npz does not match its sha256"),
    (["train", "gail", "--task", "reacher4"], "corrupt_demos", "does not match its sha256"),
    (["sweep", "table1", "--hours", "0"], None, "positive finite number"),
    (["sweep", "table1", "--hours", "nan"], None, "positive finite number"),
    (["sweep", "table3", "--priced-since", "2026-12-03T11:55"], None, "add --dry-run"),
    (["sweep", "table3", "--dry-run", "--priced-until", "2026-12-03T14:10"], None,
     "add --priced-since"),
    (["sweep", "table3", "--recheck", "2", "--dry-run"], None, "not 'all', --dry-run"),
    (["sweep", "all", "--recheck", "2"], None, "reruns finished cells of one study"),
    (["sweep", "table3", "--recheck", "2", "--cpus", "2"], None, "--address or --cpus"),
    (["sweep", "table3", "--recheck", "0"], None, "must be at least 1"),
    (["sweep", "table3", "--recheck", "1", "--only", "task=nowhere"], None,
     "matches none of the study"),
    # issue 42: --cpus 0 meant every core, -1 failed only after Ray started
    (["sweep", "bc_demos", "--cpus", "0"], None, "--cpus: must be at least 1"),
    (["sweep", "bc_demos", "--cpus", "-1"], None, "--cpus: must be at least 1"),
    (["sweep", "all", "--dry-run", "--cpus", "0"], None, "--cpus: must be at least 1"),
    (["train", "bc", "--task", "cartpole", "--steps", "5000"], None, "leave out --steps"),
    (["train", "ppo", "--task", "cartpole", "--steps", "0"], None, "must be at least 1"),
    (["train", "bc", "--task", "cartpole", "--save", "/proc/bc.pt"], None,
     "files cannot be made in /proc"),
    (["aggregate", "bc_demos"], "typo_data", "DC_LESSON_DATA=.*does not exist.*mkdir -p"),
    (["sweep", "bc_demos", "--dry-run"], "typo_data", "DC_LESSON_DATA=.*does not exist"),
]


@pytest.mark.parametrize("argv, needs, message", CASES, ids=[" ".join(c[0]) for c in CASES])
def test_bad_input_gets_one_line_and_status_2(argv, needs, message, capsys, tmp_path,
                                              request, monkeypatch):
    monkeypatch.setenv("DC_LESSON_BUDGET", "smoke")
    monkeypatch.delenv("DC_LESSON_DEBUG", raising=False)
    if needs == "a_file":
        (tmp_path / "file.txt").write_text("a file, not a folder")
    elif needs == "damaged_expert":
        d = request.getfixturevalue("expert_copy")
        data = bytearray((d / "hopper.pt").read_bytes())
        data[5000] ^= 0x04   # one bit
        (d / "hopper.pt").write_bytes(bytes(data))
    elif needs == "typo_data":
        monkeypatch.setenv("DC_LESSON_DATA", str(tmp_path / "typo"))
    elif needs is not None:
        request.getfixturevalue(needs)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code, err = run(argv, capsys)
    assert code == 2, err
    assert "Traceback" not in err
    assert re.search(message, err), err
    assert not (tmp_path / "typo").exists(), "a mistyped data folder was made"
    last = err.strip().splitlines()[-1]
    assert last.startswith("dc-lesson") and ("error:" in last or last.startswith("dc-lesson:"))


def test_the_refused_checkpoint_is_kept_and_restart_discards_it(expert_copy, capsys,
                                                               monkeypatch):
    ckpt = expert_copy / "checkpoints" / "hopper.ckpt"
    before = ckpt.read_bytes()
    code, _ = run(["expert", "train", "--task", "hopper", "--steps", "4096"], capsys)
    assert code == 2 and ckpt.read_bytes() == before   # the refusal changed nothing

    class Started(Exception):
        pass

    def start_training(*args, **kwargs):   # training itself is tested in test_ppo
        assert not ckpt.exists()           # the checkpoint is gone before training starts
        raise Started
    monkeypatch.setattr(trained, "train", start_training)
    with pytest.raises(Started):
        trained.train_unit("hopper", total_steps=4096, restart=True, progress=False)
    assert not ckpt.exists() and not ckpt.with_name("hopper.ckpt.sha256").exists()


def test_an_unexpected_error_is_one_line_with_status_1(capsys, monkeypatch):
    monkeypatch.delenv("DC_LESSON_DEBUG", raising=False)
    monkeypatch.setattr(cli, "cmd_tasks", lambda args: 1 / 0)
    code, err = run(["tasks"], capsys)
    assert code == 1 and "Traceback" not in err and "DC_LESSON_DEBUG=1" in err
    monkeypatch.setenv("DC_LESSON_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        cli.main(["tasks"])


def test_the_real_command_leaks_no_traceback(tmp_path):
    """The installed entry point, in a process of its own, with a damaged demonstration file
    in a data folder of its own (DC_LESSON_DATA)."""
    data = tmp_path / "data"
    data.mkdir()
    _corrupt_copy(store.DEMOS_DIR, data / "demos", "reacher4.npz")
    for sub in ("experts", "results"):
        os.symlink(store.DEMOS_DIR.parent / sub, data / sub)
    env = {**os.environ, "DC_LESSON_DATA": str(data), "DC_LESSON_BUDGET": "smoke",
           "PYTHONPATH": str(ROOT)}
    env.pop("DC_LESSON_DEBUG", None)
    for argv in (["train", "dc", "--task", "reacher4"],
                 ["expert", "eval", "--task", "cartpole", "--episodes", "0"]):
        p = subprocess.run([sys.executable, "-m", "dc_lesson.cli", *argv], env=env,
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
        assert p.stderr.strip()


def test_help_is_for_people():
    parser = cli.build_parser()
    text = parser.format_help()
    assert "``" not in text and ":func:" not in text and ":mod:" not in text
    assert "expert eval" in text
    sub = {a.dest: a for a in parser._subparsers._group_actions}["cmd"].choices
    perf = sub["perf"].format_help()
    for name, (summary, _) in cli.PERFS.items():
        assert name in perf and summary in perf
    assert "bench" not in sub, "the one-process studies are cell studies now: dc-lesson sweep"
    assert "--restart" in sub["expert"].format_help()


def test_help_lists_every_registered_learner():
    from dc_lesson.algorithms import ALGORITHMS
    assert tuple(ALGORITHMS) == cli.LEARNERS
    sub = {a.dest: a for a in cli.build_parser()._subparsers._group_actions}["cmd"].choices
    text = " ".join(sub["train"].format_help().split())
    assert all(name in text for name in ALGORITHMS) and "--steps" in text


def test_steps_sets_every_interacting_learners_interactions():
    from dc_lesson import budget
    from dc_lesson.algorithms import ALGORITHMS
    from dc_lesson.cli.run import learner_config
    for b in (budget.get("smoke"), budget.get("lesson")):
        for name, algo in ALGORITHMS.items():
            if name == "bc":
                continue
            config = learner_config(algo, b, 0, 40_960)
            if name == "dc":   # whole iterations per loop
                total = config.loops * config.iterations * config.batch_size
                assert 40_960 - config.loops * config.batch_size < total <= 40_960, total
                continue
            total = getattr(config, "total_steps", None) or config.ppo.total_steps
            assert total == 40_960, (b.name, name, total)


def test_the_data_folder_set_after_import_moves_every_reader_and_writer(tmp_path, monkeypatch,
                                                                        capsys):
    """The issue: demos, experts and results were fixed at import, cells read per call, so
    `aggregate` read the new folder's cells and overwrote the package's STUDY.json."""
    from dc_lesson import storage
    from dc_lesson.experiments import cells
    package = storage.data_root()
    committed = (package / "results" / "bc_demos.json").read_bytes()
    for study in ("bc_demos", "reference"):
        shutil.copytree(package / "results" / "cells" / study,
                        tmp_path / "results" / "cells" / study)
    for sub in ("demos", "experts"):
        (tmp_path / sub).symlink_to(package / sub)
    monkeypatch.setenv("DC_LESSON_DATA", str(tmp_path))   # what %env does in a chapter
    for where in (store.DEMOS_DIR, trained.EXPERTS_DIR, storage.RESULTS, cells.cells_root()):
        assert pathlib.Path(where).is_relative_to(tmp_path), where
    assert cli.main(["aggregate", "bc_demos", "--budget", "lesson"]) == 0
    assert str(tmp_path / "results" / "bc_demos.json") in capsys.readouterr().out
    assert (package / "results" / "bc_demos.json").read_bytes() == committed
    monkeypatch.delenv("DC_LESSON_DATA")
    assert pathlib.Path(store.DEMOS_DIR) == package / "demos"


def test_compiling_the_cheetahs_logs_no_settotalmass_warning(caplog, monkeypatch):
    """`dc-lesson tour` began with two absl warnings (dm_control's cheetah.xml uses MuJoCo's
    deprecated settotalmass); they are dropped where the model compiles, nothing else is."""
    import logging

    from dc_lesson import tasks
    for name in ("halfcheetah", "halfcheetah2"):
        monkeypatch.delitem(tasks._MODELS, name, raising=False)
    with caplog.at_level(logging.INFO):
        tasks.make("halfcheetah")
        tasks.make("halfcheetah2")
        logging.getLogger("absl").warning("another absl warning")
    assert [r.getMessage() for r in caplog.records] == ["another absl warning"]


@pytest.mark.parametrize("cpus", [0, -1, True, 1.5])
def test_a_sweep_from_python_refuses_a_worker_count_that_is_not_positive(cpus):
    from dc_lesson import budget
    from dc_lesson.experiments import sweep
    with pytest.raises(sweep.SweepError, match="positive whole number"):
        sweep.start_ray(budget.get("smoke"), cpus=cpus)


def _never(what):
    def fail(*a, **k):
        raise AssertionError(f"{what} before the refusal")
    return fail


def test_a_sweep_from_python_refuses_cpus_0_before_touching_anything(tmp_path, monkeypatch):
    # issue 42: run() let cpus=0 through to Ray's start (and with nothing left to run, at all)
    from dc_lesson import budget
    from dc_lesson.experiments import sweep
    monkeypatch.setattr(sweep, "plan", _never("planned"))
    root = tmp_path / "cells"
    with pytest.raises(sweep.SweepError, match="positive whole number of workers, got 0"):
        sweep.run("bc_demos", budget.get("smoke"), root=root, cpus=0, progress=False)
    assert not root.exists()


def test_a_sweep_whose_aggregate_cannot_be_written_fails_before_planning(tmp_path, monkeypatch):
    from dc_lesson import budget
    from dc_lesson.experiments import aggregate, sweep
    monkeypatch.setattr(sweep, "plan", _never("planned"))
    with pytest.raises(aggregate.AggregateError,
                       match="results folder /proc/dc-lesson-results cannot be written.*"
                             "nothing was computed"):
        sweep.run("bc_demos", budget.get("smoke"), root=tmp_path / "cells",
                  results="/proc/dc-lesson-results", progress=False)
    # without the aggregate there is nothing to write there: the sweep goes on to plan
    with pytest.raises(AssertionError, match="planned"):
        sweep.run("bc_demos", budget.get("smoke"), root=tmp_path / "cells",
                  results="/proc/dc-lesson-results", progress=False, aggregate=False)
