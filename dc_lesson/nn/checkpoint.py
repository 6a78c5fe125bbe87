"""One way to write and read every model file: atomically, and loaded with ``weights_only=True``.

Policies, PPO / GAIL / DC checkpoints and SoftFlow models are all dicts of tensors and strings
saved with :func:`atomic_torch_save` and read back with :func:`load_checked`, which checks the
file's format tag and version and turns every failure into a :class:`ModelFileError` naming
the file.
"""

from __future__ import annotations

import os
import pathlib
import uuid

import torch


class ModelFileError(ValueError):
    """A saved model file (policy, PPO checkpoint, SoftFlow) that cannot be read, or is not
    what it should be."""


PolicyFileError = ModelFileError   # the name the policy code and its tests use


def atomic_torch_save(obj, path) -> pathlib.Path:
    """``torch.save`` via a temporary file and a rename, so a crash never leaves half a file."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # A plain open (not mkstemp) so the file gets the usual permissions, not 0600.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "xb") as f:
            torch.save(obj, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if tmp.exists():
            tmp.unlink()
        raise
    return path


def load_checked(path, fmt: str, version: int, what: str) -> dict:
    """Loads a file written by :func:`atomic_torch_save` and checks its format tag.

    Raises ``FileNotFoundError`` or :class:`PolicyFileError`, each naming the file and the fault.
    """
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} file {path} does not exist")
    try:
        obj = torch.load(path, weights_only=True, map_location="cpu")
    except Exception as e:  # torch raises several types for a damaged or foreign file
        raise PolicyFileError(f"{what} file {path} could not be read: it is damaged or not a "
                              f"torch file ({type(e).__name__}: {e})") from None
    if not isinstance(obj, dict) or obj.get("format") != fmt:
        found = obj.get("format") if isinstance(obj, dict) else type(obj).__name__
        raise PolicyFileError(f"{path} is not a {what} file: expected format {fmt!r}, "
                              f"found {found!r}")
    if obj.get("version") != version:
        raise PolicyFileError(f"{what} file {path} has version {obj.get('version')!r}; this "
                              f"code reads version {version}")
    return obj


__all__ = ["ModelFileError", "PolicyFileError", "atomic_torch_save", "load_checked"]
