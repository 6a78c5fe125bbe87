"""One way to write and read every model file: atomically, checksummed, ``weights_only=True``.

Policies (the experts in ``data/experts/*.pt`` among them), PPO / GAIL / DC checkpoints and
SoftFlow models are all dicts of tensors and strings saved with :func:`atomic_torch_save` and
read back with :func:`load_checked`.

Integrity: beside every file ``X`` the writer puts ``X.sha256``, in ``sha256sum``'s format
(``DIGEST  X``; ``sha256sum -c X.sha256`` checks it by hand).  :func:`load_checked` compares the
file's sha256 with it *before* unpickling anything, so a flipped bit or a changed file is
refused instead of loading changed weights.  A sidecar (not a digest inside the file) leaves
the committed expert files byte for byte as they were.  Replacing a file takes two renames,
so for the instant between them the sidecar lists both the new digest and the old one: a
writer killed at any point leaves a file that matches its sidecar.

Every failure is a :class:`ModelFileError` naming the file and the command that makes it again
(the ``fix`` argument); torch's own advice for a refused file (to retry with
``weights_only=False``, i.e. to run whatever the file holds) is never passed on.
"""

from __future__ import annotations

import hashlib
import io
import os
import pathlib

import torch

from dc_lesson.storage import (NotRegularFileError, UnreadableFileError, atomic_write,
                               atomic_write_text, read_bytes, read_text, sha256)


class ModelFileError(ValueError):
    """A saved model file (policy, checkpoint, SoftFlow) that cannot be read, fails its
    checksum, or is not what it should be."""


PolicyFileError = ModelFileError   # the name the policy code and its tests use

CHECKSUM_SUFFIX = ".sha256"


def checksum_path(path) -> pathlib.Path:
    """The sidecar holding ``path``'s sha256: ``path`` + ``.sha256``."""
    path = pathlib.Path(path)
    return path.with_name(path.name + CHECKSUM_SUFFIX)


def _sidecar_text(path: pathlib.Path, *digests: str) -> str:
    return "".join(f"{d}  {path.name}\n" for d in digests)


def read_checksums(path, strict: bool = False, fix: str = "") -> list[str]:
    """The digests ``path``'s sidecar accepts (usually one); [] if it has none or a bad one.

    Only lines naming ``path`` itself count: a sidecar copied with another model's file
    (``hopper.pt.sha256`` over ``walker.pt.sha256``) accepts nothing.  A sidecar that is not a
    regular file (a FIFO, a link to a device) is never read; with ``strict`` it is an error."""
    path = pathlib.Path(path)
    side = checksum_path(path)
    try:
        fix = fix or f"rerun the command that wrote {path.name}"
        lines = read_text(side, "checksum file", f"delete it; {fix}").splitlines()
    except NotRegularFileError:
        if strict:
            raise
        return []
    except (OSError, UnreadableFileError):   # no sidecar, or garbage: it accepts nothing
        return []
    out = []
    for line in lines:
        digest, _, name = line.partition(" ")
        digest, name = digest.strip().lower(), name.strip().lstrip("*")
        if len(digest) == 64 and all(c in "0123456789abcdef" for c in digest) \
                and name == path.name:
            out.append(digest)
    return out


def write_checksum(path) -> pathlib.Path:
    """Writes the sidecar of an existing file (for files made before sidecars existed, such
    as the committed experts); returns the sidecar's path."""
    path = pathlib.Path(path)
    atomic_write_text(checksum_path(path), _sidecar_text(path, sha256(path)))
    return checksum_path(path)


def atomic_torch_save(obj, path) -> pathlib.Path:
    """``torch.save`` via a temporary file and a rename, with its sha256 in ``path.sha256``.

    Stale temporary files of killed saves in the folder are removed first
    (:func:`dc_lesson.storage.remove_stale_temps`)."""
    path = pathlib.Path(path)
    digest = {}

    def write(f):
        torch.save(obj, f)
        f.flush()
        os.fsync(f.fileno())
        digest["new"] = sha256(f.name)

    # The sidecar first accepts the old and the new digest, then (after the rename) only the new.
    # "The old" is the digest of the file on disk now, if its sidecar accepts it: after a save
    # killed before its rename, the sidecar's first line is that save's digest, not the file's.
    side = checksum_path(path)
    old = []
    if path.is_file():
        current = sha256(path)
        old = [current] if current in read_checksums(path) else []

    def write_and_announce(f):
        write(f)
        atomic_write_text(side, _sidecar_text(path, digest["new"], *old))

    atomic_write(path, write_and_announce)
    atomic_write_text(side, _sidecar_text(path, digest["new"]))
    return path


def _torch_reason(e: Exception) -> str:
    """A one-line reason for torch's refusal, without its advice to unpickle anyway."""
    text = str(e)
    if "weights_only" in text or "Unpickl" in type(e).__name__ or "pickle" in text.lower():
        return ("it holds Python objects other than tensors and plain values, which the "
                "library never writes; it was refused without running them")
    first = text.strip().splitlines()[0] if text.strip() else ""
    return f"it is damaged or not a torch file ({type(e).__name__}: {first[:200]})"


def load_checked(path, fmt: str, version: int, what: str, fix: str | None = None) -> dict:
    """Loads a file written by :func:`atomic_torch_save`: checks its sha256 against its
    sidecar, loads it with ``weights_only=True`` and checks its format tag and version.

    ``fix`` says how to make the file again (default: delete it and rerun the command that
    wrote it).  Raises ``FileNotFoundError`` or :class:`ModelFileError`, each naming the file,
    the fault and the fix.
    """
    path = pathlib.Path(path)
    fix = fix or f"delete it and rerun the command that wrote it"
    if not path.exists():
        raise FileNotFoundError(f"{what} file {path} does not exist; {fix}")
    try:
        blob = read_bytes(path, f"{what} file", fix)   # one read: hashed, then loaded
        accepted = read_checksums(path, strict=True, fix=fix)
    except NotRegularFileError as e:
        raise ModelFileError(str(e)) from None
    if not accepted:
        raise ModelFileError(f"{what} file {path} has no checksum file "
                             f"{checksum_path(path).name} naming it (none, an unreadable one, or "
                             f"one copied from another file), so its integrity cannot be "
                             f"checked; {fix}")
    digest = hashlib.sha256(blob).hexdigest()
    if digest not in accepted:
        raise ModelFileError(f"{what} file {path} does not match its sha256 in "
                             f"{checksum_path(path).name} (file {digest[:12]}..., recorded "
                             f"{accepted[0][:12]}...): it is corrupted or was changed; {fix}")
    try:
        obj = torch.load(io.BytesIO(blob), weights_only=True, map_location="cpu")
    except Exception as e:  # torch raises several types for a damaged or foreign file
        raise ModelFileError(f"{what} file {path} could not be read: {_torch_reason(e)}; "
                             f"{fix}") from None
    if not isinstance(obj, dict) or obj.get("format") != fmt:
        found = obj.get("format") if isinstance(obj, dict) else type(obj).__name__
        raise ModelFileError(f"{path} is not a {what} file: expected format {fmt!r}, "
                             f"found {found!r}; {fix}")
    if obj.get("version") != version:
        raise ModelFileError(f"{what} file {path} has version {obj.get('version')!r}; this "
                             f"code reads version {version}; {fix}")
    return obj


__all__ = ["CHECKSUM_SUFFIX", "ModelFileError", "PolicyFileError", "atomic_torch_save",
           "checksum_path", "load_checked", "read_checksums", "write_checksum"]
