"""Opening and saving a chapter in Jupyter leaves its pair byte-identical.

A reader who opens ``book/NN_name.ipynb`` in JupyterLab and saves it must not get a git diff in
either file. One Jupyter server (with jupytext's contents manager, as JupyterLab runs it) on a
copy of ``book/`` and of the repository's jupytext configuration GETs every chapter through
the contents API and PUTs it back unchanged; both files must keep their bytes. Two more checks
keep the test honest: an edited notebook does reach its ``.py`` (so the pairing really is live
in the server), and a new notebook is paired by the repository's configuration alone.
"""

from __future__ import annotations

import json
import os
import pathlib
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
BOOK = ROOT / "book"
CHAPTERS = sorted(p.name for p in BOOK.glob("[0-9][0-9]_*.ipynb"))


def test_the_repository_pairs_notebooks_with_percent_scripts():
    from jupytext.config import find_jupytext_configuration_file, load_jupytext_config
    path = find_jupytext_configuration_file(str(BOOK))
    assert path is not None and pathlib.Path(path).resolve() == ROOT / "pyproject.toml"
    formats = load_jupytext_config(str(BOOK / CHAPTERS[0])).formats
    assert formats in ("ipynb,py:percent", ["ipynb,py:percent"]), formats
    assert CHAPTERS and all((BOOK / c).with_suffix(".py").exists() for c in CHAPTERS)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A Jupyter server on a copy of book/ and pyproject.toml: (api, folder)."""
    work = tmp_path_factory.mktemp("roundtrip")
    (work / "book").mkdir()
    for c in CHAPTERS:
        for suffix in (".ipynb", ".py"):
            shutil.copy2(BOOK / c.replace(".ipynb", suffix), work / "book")
    shutil.copy2(ROOT / "pyproject.toml", work / "pyproject.toml")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    token = secrets.token_hex(16)
    log = open(work / "server.log", "w")
    # jupyter_server with its installed extensions: the jupytext one replaces the contents
    # manager, exactly as under `jupyter lab` (lighter and faster to start than the Lab).
    proc = subprocess.Popen(
        [sys.executable, "-m", "jupyter_server", "--allow-root", "--no-browser",
         "--ServerApp.ip=127.0.0.1", f"--ServerApp.port={port}", "--ServerApp.port_retries=0",
         f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={work}"],
        cwd=work, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
        env={**os.environ, "JUPYTER_CONFIG_DIR": str(work / ".jupyter")})
    base = f"http://127.0.0.1:{port}"

    def api(path, method="GET", body=None):
        req = urllib.request.Request(
            base + path, method=method,
            data=None if body is None else json.dumps(body).encode(),
            headers={"Authorization": f"token {token}", "Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            return json.loads(r.read() or b"null")

    try:
        t0 = time.monotonic()
        while True:
            try:
                api("/api/status")
                break
            except (urllib.error.URLError, OSError):
                if proc.poll() is not None or time.monotonic() - t0 > 60:
                    pytest.fail("the Jupyter server did not start:\n"
                                + (work / "server.log").read_text()[-3000:])
                time.sleep(0.3)
        yield api, work
    finally:
        try:
            os.killpg(proc.pid, signal.SIGTERM)   # the server this fixture started
            proc.wait(timeout=20)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            os.killpg(proc.pid, signal.SIGKILL)
        log.close()


def save(api, path, nb):
    return api(f"/api/contents/{path}", "PUT", {"type": "notebook", "format": "json",
                                                "content": nb})


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_saving_a_chapter_unchanged_leaves_both_files_byte_identical(server, chapter):
    api, work = server
    got = api(f"/api/contents/book/{chapter}?type=notebook&content=1")
    assert got["type"] == "notebook" and got["content"]["cells"]
    save(api, f"book/{chapter}", got["content"])
    for suffix in (".ipynb", ".py"):
        name = chapter.replace(".ipynb", suffix)
        saved, original = (work / "book" / name).read_bytes(), (BOOK / name).read_bytes()
        assert saved == original, f"saving {chapter} through Jupyter changed {name}"


def test_an_edited_notebook_reaches_its_py(server):
    """The control: saving does write the pair, so the byte comparison above can fail."""
    api, work = server
    chapter = CHAPTERS[0]
    nb = api(f"/api/contents/book/{chapter}?type=notebook&content=1")["content"]
    nb["cells"].append({"cell_type": "markdown", "metadata": {}, "source": "A reader's note.",
                        "id": "readers-note"})
    save(api, f"book/{chapter}", nb)
    py = (work / "book" / chapter.replace(".ipynb", ".py")).read_text()
    assert py.endswith("# %% [markdown]\n# A reader's note.\n")


def test_a_new_notebook_is_paired_by_the_repository_configuration(server):
    api, work = server
    nb = {"nbformat": 4, "nbformat_minor": 5, "metadata": {},
          "cells": [{"cell_type": "code", "metadata": {}, "source": "x = 1", "outputs": [],
                     "execution_count": None, "id": "new-cell"}]}
    save(api, "book/99_new.ipynb", nb)
    assert (work / "book" / "99_new.py").read_text().rstrip().endswith("# %%\nx = 1")


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_chapters_name_the_kernel_jupyterlab_runs_them_with(chapter):
    """JupyterLab writes the running kernel's spec into the notebook when it saves; a chapter
    that names another display name gets its .py header rewritten by a reader's first save."""
    from jupyter_client.kernelspec import KernelSpecManager
    spec = KernelSpecManager().get_kernel_spec("python3")
    meta = json.loads((BOOK / chapter).read_text())["metadata"]["kernelspec"]
    assert meta == {"name": "python3", "display_name": spec.display_name,
                    "language": spec.language}
