"""Where the library's files live, and how it writes them: the bottom layer every other reads.

* :func:`data_root` is the one data folder (``demos/``, ``experts/``, ``results/``).  It is
  found the same way from a copy of the repository, an editable install and a wheel: the
  package's ``_data`` entry, which in the repository is a link to the top-level ``data/``
  folder and in a wheel is that folder's copy.  The environment variable ``DC_LESSON_DATA``
  overrides it (a folder of your own, e.g. for a read-only install).  It is read at every use,
  never fixed at import: :data:`DATA` and :data:`RESULTS` (and the modules' ``DEMOS_DIR`` and
  ``EXPERTS_DIR`` made from them) are :class:`DataPath` views that resolve when used, so a
  variable set after import (``%env`` in a notebook) moves every reader and writer at once.
  A ``DC_LESSON_DATA`` naming no folder is refused, never created and filled.
* Every reader opens files through :func:`open_regular`: a FIFO (which would block forever)
  or a device (a link to ``/dev/zero`` reads until memory runs out) is refused by name.
* Writes are atomic (a temporary file ``.NAME.PID.XXXXXXXX.tmp``, then a rename), so a crash
  never leaves half a file; a temporary file a killed writer left behind is removed by the next
  write into the same folder (see :func:`remove_stale_temps`).
* Result files under ``results/`` are JSON with the provenance every stored figure carries
  (the command that made it, seeds, budget, git revision, time).  The JSON is strictly
  standard: a NaN or infinity (a run that recorded no value) is written as ``null``.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import math
import os
import pathlib
import re
import stat
import subprocess
import time
import uuid

from dc_lesson import budget as _budget

ROOT = pathlib.Path(__file__).resolve().parent.parent   # the repository (or site-packages)
DATA_ENV = "DC_LESSON_DATA"


PACKAGE_DATA = pathlib.Path(__file__).resolve().parent / "_data"


class DataFolderError(ValueError):
    """``DC_LESSON_DATA`` names no folder (a typo would otherwise be created and filled)."""


def data_root() -> pathlib.Path:
    """The data folder: ``$DC_LESSON_DATA`` if set (it must be an existing folder), else the
    package's ``_data``.  Read at every call: the one place the data folder is decided."""
    env = os.environ.get(DATA_ENV)
    if not env:
        return PACKAGE_DATA
    path = pathlib.Path(env).expanduser().resolve()
    if not path.is_dir():
        problem = "is a file, not a folder" if path.exists() else "does not exist"
        raise DataFolderError(f"{DATA_ENV}={env} {problem}; the data folder must exist (make "
                              f"it with: mkdir -p {path}, and copy the package's data into it "
                              f"with: cp -r {PACKAGE_DATA}/. {path}), or unset {DATA_ENV} to "
                              f"use {PACKAGE_DATA}")
    return path


class DataPath(os.PathLike):
    """A path inside the data folder, resolved at each use (:func:`data_root`), so a module
    constant such as ``DATA / "demos"`` follows ``DC_LESSON_DATA`` set after import.
    ``pathlib.Path(p)`` and ``os.fspath(p)`` give today's path; ``p / "x"`` another view;
    any other attribute is today's ``pathlib.Path``'s."""

    def __init__(self, *parts: str):
        self._parts = tuple(str(x) for x in parts)

    def now(self) -> pathlib.Path:
        return data_root().joinpath(*self._parts)

    def __fspath__(self) -> str:
        return str(self.now())

    __str__ = __fspath__

    def __repr__(self) -> str:
        return f"DataPath({'/'.join(('DATA',) + self._parts)})"

    def __truediv__(self, other) -> "DataPath":
        return DataPath(*self._parts, other)

    def __getattr__(self, name):
        return getattr(self.now(), name)

    def __eq__(self, other) -> bool:
        if isinstance(other, DataPath):
            return self._parts == other._parts
        return isinstance(other, (str, os.PathLike)) and self.now() == pathlib.Path(other)

    def __hash__(self) -> int:
        return hash(self._parts)


DATA = DataPath()
RESULTS = DATA / "results"


class NotRegularFileError(ValueError):
    """A file to read that is a FIFO, a device, a folder or a socket."""


def _kind(mode: int) -> str:
    return ("a folder" if stat.S_ISDIR(mode) else "a FIFO (named pipe)" if stat.S_ISFIFO(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")


def open_regular(path, what: str = "file", fix: str = ""):
    """``path`` opened for binary reading, only if it is (or links to) a regular file.

    The open does not block (``O_NONBLOCK``: a FIFO with no writer would wait forever) and the
    kind is taken from the opened file itself (``fstat``), so a link to ``/dev/zero`` is
    refused before a byte is read.  Raises :class:`NotRegularFileError` naming ``what``,
    the file, its kind and ``fix``; ``FileNotFoundError`` as ``open`` does."""
    path = pathlib.Path(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotRegularFileError(f"{what} {path} is {_kind(mode)}, not a regular file; "
                                      f"{fix or 'replace it with the file the library wrote'}")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path, what: str = "file", fix: str = "") -> bytes:
    """The bytes of a regular file (:func:`open_regular`)."""
    with open_regular(path, what, fix) as f:
        return f.read()


class UnreadableFileError(ValueError):
    """A file whose bytes are not what the library writes (not UTF-8 text, not JSON, a field
    missing); the message names the file and how to make it again."""


def read_text(path, what: str = "file", fix: str = "") -> str:
    """The UTF-8 text of a regular file (:func:`open_regular`); bytes that are not UTF-8 raise
    :class:`UnreadableFileError` naming the file (the codec's own message names none)."""
    try:
        return read_bytes(path, what, fix).decode()
    except UnicodeDecodeError as e:
        raise UnreadableFileError(f"{what} {path} is not UTF-8 text (byte {e.start}); "
                                  f"{fix or 'replace it with the file the library wrote'}"
                                  ) from None


def read_json(path, what: str = "file", fix: str = ""):
    """The JSON value in a regular UTF-8 file; a file that does not parse raises
    :class:`UnreadableFileError` naming it (``json``'s message gives a line, not a file)."""
    try:
        return json.loads(read_text(path, what, fix))
    except json.JSONDecodeError as e:
        raise UnreadableFileError(f"{what} {path} is not valid JSON ({e}); "
                                  f"{fix or 'replace it with the file the library wrote'}"
                                  ) from None


def json_fields(value, path, what: str, fix: str, *keys: str) -> list:
    """``value[key]`` for each key of a JSON object read from ``path``; a value that is not an
    object, or lacks a key, raises :class:`UnreadableFileError` naming the file and the key
    (a bare ``KeyError: 'log'`` names neither)."""
    if not isinstance(value, dict):
        raise UnreadableFileError(f"{what} {path} holds {type(value).__name__}, not a JSON "
                                  f"object; {fix}")
    missing = [k for k in keys if k not in value]
    if missing:
        raise UnreadableFileError(f"{what} {path} lacks {', '.join(map(repr, missing))}; {fix}")
    return [value[k] for k in keys]


def git_revision() -> str:
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                             text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, capture_output=True, text=True, timeout=10).stdout.strip()
        return (rev or "unknown") + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def platform_info() -> dict:
    """What a number depends on beyond the seed: the CPU and its vector instructions and the
    numerical libraries' versions.  A cell or benchmark records it because the same seed gives
    the same bits only on the same kind of machine: NumPy and PyTorch choose their kernels for
    the CPU at run time (AVX2, AVX-512, ...), whose float rounding differs, and an RL run
    amplifies a last-bit difference into a different trajectory (README, Sweeps).  Across machines a cell is
    another sample of the same experiment, not the same numbers."""
    import platform as _platform

    import mujoco
    import numpy
    import torch
    cpu = _platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f
                        if line.startswith("model name")), cpu)
    except OSError:
        pass
    return {"cpu": cpu or _platform.machine(), "machine": _platform.machine(),
            "torch_cpu_capability": torch.backends.cpu.get_cpu_capability(),
            "python": _platform.python_version(), "numpy": numpy.__version__,
            "torch": torch.__version__, "mujoco": mujoco.__version__}


def sha256(path) -> str:
    """The hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open_regular(path) as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# Our temporary files: ".NAME.PID.XXXXXXXX.tmp" (the pid says whose; 8 hex digits make it
# unique), and the older "NAME.XXXXXXXX.tmp" of tempfile.mkstemp (8 of [a-z0-9_]).
_TEMP = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[0-9a-f]{8}\.tmp$")
_OLD_TEMP = re.compile(r"^(?P<name>[^.].*\.(json|npz|pt|ckpt|sha256))\.[a-z0-9_]{8}\.tmp$")
STALE_SECONDS = 3600   # a temporary file this old is stale whoever wrote it (pids are reused)


def temp_path(path) -> pathlib.Path:
    """The temporary file an atomic write of ``path`` goes through (same folder, so the rename
    is atomic)."""
    path = pathlib.Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True   # someone else's process (or a pid we cannot ask about): assume alive
    return True


def remove_stale_temps(folder, now: float | None = None) -> list[pathlib.Path]:
    """Removes the temporary files of killed writes in ``folder``; returns those removed.

    Only files named like our own temporaries are touched, and only if their writer's process
    is gone (another live process may be writing right now) or they are older than
    :data:`STALE_SECONDS`; the older mkstemp names carry no pid, so only age counts for them.
    """
    folder = pathlib.Path(folder)
    now = time.time() if now is None else now
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m, old = _TEMP.match(entry.name), _OLD_TEMP.match(entry.name)
        if not (m or old):
            continue
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            age = now - entry.stat(follow_symlinks=False).st_mtime
            pid = int(m["pid"]) if m else None
            if age > STALE_SECONDS or (pid is not None and pid != os.getpid()
                                       and not _pid_alive(pid)):
                os.unlink(entry.path)
                removed.append(pathlib.Path(entry.path))
        except OSError:
            continue   # removed meanwhile by another cleaner, or not ours to remove
    return removed


def atomic_write(path, write) -> pathlib.Path:
    """Calls ``write(f)`` on a temporary file beside ``path``, syncs it, and renames it to
    ``path``, so a crash never leaves half a file; first removes stale temporaries there."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(path.parent)
    tmp = temp_path(path)
    try:
        # A plain open (not mkstemp) so the file gets the usual permissions, not 0600.
        with open(tmp, "xb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if tmp.exists():
            tmp.unlink()
        raise
    return path


def atomic_write_text(path, text: str) -> None:
    """Writes via a temporary file and a rename, so a crash never leaves half a file."""
    atomic_write_bytes(path, text.encode())


def atomic_write_bytes(path, data: bytes) -> None:
    """Writes via a temporary file and a rename, so a crash never leaves half a file."""
    atomic_write(path, lambda f: f.write(data))


class OutputPathError(ValueError):
    """An output path that cannot be written (a folder, a file in an unwritable folder, ...)."""


def check_writable(path, folder: bool = False) -> pathlib.Path:
    """Checks, before any compute, that ``path`` can be written: a file (or with ``folder``,
    a folder) that is not the other kind, in a folder that exists or can be made and lets us
    write.  Makes no file; returns the path.  Raises :class:`OutputPathError`."""
    path = pathlib.Path(path).expanduser()
    kind = "folder" if folder else "file"
    if path.exists() and path.is_dir() != folder:
        raise OutputPathError(f"the output {kind} {path} is a {'file' if folder else 'folder'}; "
                              f"give a {kind} path")
    if folder and path.is_dir():
        target = path
    else:
        target = path.parent
        while not target.exists() and target != target.parent:
            target = target.parent   # the deepest existing folder: the rest will be made
        if not target.is_dir():
            raise OutputPathError(f"cannot write {path}: {target} is a file, not a folder")
    if not os.access(target, os.W_OK | os.X_OK):
        raise OutputPathError(f"cannot write {path}: no write permission in {target}; choose "
                              f"another path")
    # Permission bits do not tell everything (/proc, a read-only mount, a full disk for root):
    # a file made and removed there does.
    probe = target / f".write-check.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
    try:
        with open(probe, "xb") as f:
            f.write(b"0")
        probe.unlink()
    except OSError as e:
        raise OutputPathError(f"cannot write {path}: files cannot be made in {target} "
                              f"({e.strerror or e}); choose another path") from None
    if not folder and path.exists() and not os.access(path, os.W_OK) \
            and not os.access(path.parent, os.W_OK):
        raise OutputPathError(f"cannot overwrite {path}; choose another path")
    return path


def _standard(value):
    """``value`` with every NaN or infinity replaced by None (JSON's null), recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _standard(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_standard(v) for v in value]
    if hasattr(value, "tolist"):   # numpy scalars and arrays
        return _standard(value.tolist())
    return value


def dumps_standard(obj, **kwargs) -> str:
    """JSON that every parser reads: NaN and infinities become ``null`` (never the
    non-standard ``NaN``), numpy values become plain numbers."""
    return json.dumps(_standard(obj), allow_nan=False, **kwargs)


def write_result(path, payload: dict, *, command: str, seeds) -> pathlib.Path:
    """Writes ``payload`` with its provenance as standard JSON: a NaN or infinity (a value that
    was not measured, e.g. a log row of an update in which no episode ended) is written as
    ``null``, which ``np.asarray(values, dtype=float)`` reads back as NaN."""
    path = pathlib.Path(path)
    record = {"command": command, "seeds": list(seeds), "budget": _budget.current().name,
              "revision": git_revision(),
              "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "platform": platform_info(), **payload}
    atomic_write_text(path, dumps_standard(record, indent=1) + "\n")
    return path


def read_result(name_or_path) -> dict:
    path = pathlib.Path(name_or_path)
    if not path.is_absolute() and not path.exists():
        path = RESULTS / path
    try:
        return read_json(path, "result file", "regenerate it")
    except FileNotFoundError:
        raise FileNotFoundError(f"result file {path} is missing; it is made by the command "
                                f"recorded in the book beside the figure") from None
