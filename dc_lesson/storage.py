"""Where the library's files live, and how it writes them: the bottom layer every other reads.

* :data:`DATA` is the one data folder (``demos/``, ``experts/``, ``results/``).  It is found the
  same way from a copy of the repository, an editable install and a wheel: the package's
  ``_data`` entry, which in the repository is a link to the top-level ``data/`` folder and in a
  wheel is that folder's copy.  The environment variable ``DC_LESSON_DATA`` overrides it (a
  folder of your own, e.g. for a read-only install).
* Writes are atomic (a temporary file, then a rename), so a crash never leaves half a file.
* Result files under ``results/`` are JSON with the provenance every stored figure carries
  (the command that made it, seeds, budget, git revision, time).
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
import subprocess
import tempfile

from dc_lesson import budget as _budget

ROOT = pathlib.Path(__file__).resolve().parent.parent   # the repository (or site-packages)
DATA_ENV = "DC_LESSON_DATA"


def data_root() -> pathlib.Path:
    """The data folder: ``$DC_LESSON_DATA`` if set, else the package's ``_data``."""
    env = os.environ.get(DATA_ENV)
    if env:
        return pathlib.Path(env).expanduser().resolve()
    return pathlib.Path(__file__).resolve().parent / "_data"


DATA = data_root()
RESULTS = DATA / "results"


def git_revision() -> str:
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                             text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, capture_output=True, text=True, timeout=10).stdout.strip()
        return (rev or "unknown") + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def atomic_write_text(path, text: str) -> None:
    """Writes via a temporary file and a rename, so a crash never leaves half a file."""
    atomic_write_bytes(path, text.encode())


def atomic_write_bytes(path, data: bytes) -> None:
    """Writes via a temporary file and a rename, so a crash never leaves half a file."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes files private; results are meant to be read
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


class NotWritableError(OSError):
    """An output path the library cannot write: found before any compute is spent."""


def check_writable(path) -> pathlib.Path:
    """Checks that ``path`` (a file to be written) can be created or replaced, before the
    compute that produces it; raises :class:`NotWritableError` naming the path and the fix."""
    path = pathlib.Path(path)
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if path.is_dir():
        raise NotWritableError(f"{path} is a folder; give a file name to write to")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and
                                                     not os.access(path, os.W_OK)):
        raise NotWritableError(f"cannot write {path}: {folder} is not writable; choose "
                               f"another output path")
    return path


def write_result(path, payload: dict, *, command: str, seeds) -> pathlib.Path:
    path = pathlib.Path(path)
    record = {"command": command, "seeds": list(seeds), "budget": _budget.current().name,
              "revision": git_revision(),
              "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              **payload}
    atomic_write_text(path, json.dumps(record, indent=1, default=float) + "\n")
    return path


def read_result(name_or_path) -> dict:
    path = pathlib.Path(name_or_path)
    if not path.is_absolute() and not path.exists():
        path = RESULTS / path
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"result file {path} is missing; it is made by the command "
                                f"recorded in the book beside the figure") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"result file {path} is not valid JSON ({e}); regenerate it") from None
