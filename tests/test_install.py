"""The data travels with the package: demonstrations load the same way from a wheel."""

import os
import pathlib
import shutil
import subprocess
import sys
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    """A wheel built from a copy of the repository (so the build leaves this tree alone)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(ROOT, src, symlinks=True,
                    ignore=shutil.ignore_patterns(".git", "build", "*.egg-info", "outputs",
                                                  "__pycache__", ".ipynb_checkpoints",
                                                  "partial", "checkpoints"))
    out = tmp / "dist"
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps",
                        "--no-build-isolation", "-q", "-w", str(out), str(src)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    (whl,) = out.glob("dc_lesson-*.whl")
    return whl


def test_the_wheel_carries_the_data(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for task in ("reacher4", "humanoid"):
        assert f"dc_lesson/_data/demos/{task}.npz" in names
    assert "dc_lesson/_data/demos/manifest.json" in names
    assert "dc_lesson/_data/experts/halfcheetah.pt" in names
    assert "dc_lesson/_data/experts/halfcheetah.pt.sha256" in names   # its checksum travels too


def test_demos_load_from_an_installed_wheel(wheel, tmp_path):
    """Unpacked as pip installs it (a site folder first on the path, no repository around),
    the package finds its demonstrations inside itself and checks them."""
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    code = ("import dc_lesson, pathlib; from dc_lesson import data, storage; "
            "d = data.load_demos('reacher2', n_trajectories=3); "
            "print(dc_lesson.__file__); print(storage.DATA); print(len(d), d.task)")
    env = {**os.environ, "PYTHONPATH": str(site)}
    env.pop("DC_LESSON_DATA", None)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       cwd=tmp_path, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    file, data_dir, loaded = r.stdout.strip().splitlines()[-3:]
    assert pathlib.Path(file).is_relative_to(site)
    assert pathlib.Path(data_dir).resolve().is_relative_to(site.resolve())
    assert loaded == "3 reacher2"


def test_the_data_folder_can_be_set(tmp_path):
    """DC_LESSON_DATA points the library at a folder of one's own."""
    (tmp_path / "demos").mkdir()
    shutil.copy(ROOT / "data" / "demos" / "manifest.json", tmp_path / "demos")
    shutil.copy(ROOT / "data" / "demos" / "cartpole.npz", tmp_path / "demos")
    code = ("from dc_lesson import data, storage; print(storage.DATA); "
            "print(len(data.load_demos('cartpole')))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={**os.environ, "DC_LESSON_DATA": str(tmp_path)}, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == [str(tmp_path.resolve()), "25"]
