"""Every result a cell: one (study, learner, task, number of demonstrations, seed, config) run.

A cell's record is one small JSON file (and, when the run keeps mode features, an ``.npz``
beside it) under ``data/results/cells/STUDY/TASK/``, named by its identity::

    LEARNER[-VARIANT]__n{N_DEMOS}__s{SEED}__{CONFIG_HASH}.json

The config is everything that decides the numbers (sizes, learner settings, the evaluation
seed, the hashes of the cells it reads, such as the fresh expert reference); its hash is the
first 12 hex digits of the SHA-256 of its canonical JSON.  A cell whose file exists with the
same hash is never recomputed: change anything in the config and the cell is new, change
nothing and a rerun skips it.

A record holds ``cell`` (the identity), ``config``, ``result`` (the numbers), ``timing`` (the
run's wall-clock figures, kept apart: :func:`split_timing`) and ``provenance`` (command,
revision, budget, torch threads, wall time, host, time).  Reruns of a cell give an identical
``cell``, ``config`` and ``result``; only ``timing`` and ``provenance`` differ.
Files are written atomically (a temporary file and a rename: a killed sweep never leaves half
a record), the ``.npz`` first so a record never points at missing features, and read back with
checks (``allow_pickle=False``; a record whose name and content disagree is refused).

Integrity, as model files have it (:mod:`dc_lesson.nn.checkpoint`): a record carries
``sha256``, the digest of its own canonical JSON without that field, and ``features_sha256``,
its ``.npz``'s; :func:`read_record` refuses a record (or features) whose bytes no longer give
them, so one digit changed by hand or by bit rot is an error naming the file, never a moved
mean.  Records written before digests existed have none: they are read (and
``dc-lesson seal-cells`` adds the digests once; every committed record has them).  Every
measure read is type-checked too (:func:`check_types`): a ``true`` or a string where a number
belongs is an error naming the file and the field.  Files are opened only if regular
(:func:`dc_lesson.storage.open_regular`): a FIFO or a link to a device is refused unread.

A :class:`Study` is a small declarative object: its cells at a budget and the function that
runs one; the studies themselves live in ``dc_lesson.experiments.studies``.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import io
import json
import pathlib
import re
from typing import Callable

import numpy as np

from dc_lesson import storage

HASH_LEN = 12
_NAME = re.compile(r"^[A-Za-z0-9_.=+-]+$")


class CellError(ValueError):
    """A cell or cell file that cannot be used (bad name, corrupt file, wrong hash)."""


def cells_root() -> pathlib.Path:
    """Where cell records live: ``DATA/results/cells`` (``DC_LESSON_DATA`` moves it)."""
    return storage.data_root() / "results" / "cells"


def canonical(config) -> str:
    """The config as canonical JSON (sorted keys, no spaces): what the hash is taken of."""
    return json.dumps(config, sort_keys=True, separators=(",", ":"), default=_jsonable)


def _jsonable(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, (tuple, set)):
        return list(x)
    raise TypeError(f"cell configs hold JSON values only, not {type(x).__name__}")


def config_hash(config) -> str:
    return hashlib.sha256(canonical(config).encode()).hexdigest()[:HASH_LEN]


@dataclasses.dataclass(frozen=True)
class Cell:
    """One run.  ``config_json`` is canonical JSON (so a cell is hashable and immutable);
    ``variant`` names a setting beside the learner (``lr=0.001``, ``loops=2``); ``stage``
    orders a sweep (cells of stage 0 first: the references others read); ``needs`` are the
    cells whose records and features this one reads."""
    study: str
    learner: str
    task: str
    n_demos: int
    seed: int
    config_json: str
    variant: str = ""
    stage: int = 1
    needs: tuple["Cell", ...] = ()

    def __post_init__(self):
        for field in ("study", "learner", "task") + (("variant",) if self.variant else ()):
            if not _NAME.match(getattr(self, field)):
                raise CellError(f"cell {field} {getattr(self, field)!r} may hold only letters, "
                                f"digits and _.=+-")

    @property
    def config(self) -> dict:
        return json.loads(self.config_json)

    @property
    def hash(self) -> str:
        return config_hash(self.config)

    @property
    def row(self) -> str:
        """The learner and its variant: the table row the cell belongs to."""
        return self.learner + (f"-{self.variant}" if self.variant else "")

    @property
    def name(self) -> str:
        return f"{self.row}__n{self.n_demos}__s{self.seed}__{self.hash}"

    def identity(self) -> dict:
        return {"study": self.study, "learner": self.learner, "variant": self.variant,
                "task": self.task, "n_demos": self.n_demos, "seed": self.seed,
                "config_hash": self.hash}

    def path(self, root=None) -> pathlib.Path:
        return pathlib.Path(root or cells_root()) / self.study / self.task / f"{self.name}.json"


def demos_identity(task: str, variant=None) -> dict | None:
    """What names a task's demonstrations in a cell's config: their sha256 and expert."""
    from dc_lesson import tasks as _tasks
    from dc_lesson.data import store
    if task not in _tasks.NAMES:
        return None   # a toy (softflow_fit's circle): no demonstrations
    try:
        entry = store.manifest_entry(task, variant=variant)
    except store.DemoError:
        return None
    return {"sha256": entry["sha256"], "expert": entry["expert"].get("name"),
            "mode_choice": entry["expert"].get("mode_choice")}


def make_cell(study: str, learner: str, task: str, n_demos: int, seed: int, config: dict, *,
              variant: str = "", stage: int = 1, needs=()) -> Cell:
    """A cell; the hashes of ``needs`` join the config, so a new reference makes new cells,
    and so do the task's demonstrations (their sha256) and its expert (its mode choice): new
    demonstrations or a new expert make new cells, never silently reuse old ones."""
    needs = tuple(needs)
    config = dict(config)
    config.setdefault("demos", demos_identity(task, config.get("demo_variant")))
    if needs:
        config["needs"] = [f"{n.study}/{n.task}/{n.name}" for n in needs]
    return Cell(study, learner, task, int(n_demos), int(seed), canonical(config), variant,
                int(stage), needs)


def features_path(json_path) -> pathlib.Path:
    return pathlib.Path(json_path).with_suffix(".npz")


def _is_timing(key: str) -> bool:
    return "seconds" in key or "per_second" in key


def split_timing(result):
    """``(numbers, timing)``: wall-clock entries (keys naming seconds) apart from the numbers
    the seed decides, keeping the nesting; a rerun repeats the first, never the second."""
    if isinstance(result, dict):
        numbers, timing = {}, {}
        for k, v in result.items():
            if _is_timing(k):
                timing[k] = v
                continue
            n, t = split_timing(v)
            numbers[k] = n
            if t:
                timing[k] = t
        return numbers, timing
    if isinstance(result, list) and any(isinstance(x, dict) for x in result):
        parts = [split_timing(x) for x in result]
        return [p[0] for p in parts], ([p[1] for p in parts] if any(p[1] for p in parts)
                                       else {})
    return result, {}


def merged(numbers, timing):
    """The result with its timing put back (what :func:`split_timing` took apart)."""
    if isinstance(numbers, dict) and isinstance(timing, dict):
        return {**{k: merged(v, timing.get(k, {})) for k, v in numbers.items()},
                **{k: v for k, v in timing.items() if k not in numbers}}
    if isinstance(numbers, list) and isinstance(timing, list):
        return [merged(n, t) for n, t in zip(numbers, timing)]
    return numbers


def full_result(record: dict) -> dict:
    return merged(record["result"], record.get("timing", {}))


def record_form(result: dict) -> tuple[dict, dict]:
    """``(numbers, timing)`` of a cell's result as its record keeps them (JSON values, NaN
    kept as NaN, wall-clock entries apart): what a rerun is compared in."""
    return split_timing(json.loads(json.dumps(result, default=_jsonable)))


DIGEST = "sha256"
FEATURES_DIGEST = "features_sha256"


def record_digest(record: dict) -> str:
    """The sha256 of a record's canonical JSON without its own digest field."""
    body = {k: v for k, v in record.items() if k != DIGEST}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":"))
                          .encode()).hexdigest()


def _sealed(record: dict) -> dict:
    return {**record, DIGEST: record_digest(record)}


def write_record(cell: Cell, result: dict, features: dict | None, provenance: dict,
                 root=None) -> pathlib.Path:
    """Writes the cell's record (and its features first) atomically; returns the JSON path.
    Wall-clock entries of ``result`` go to ``timing`` (:func:`split_timing`); the record
    carries its own digest and its features' (module docstring)."""
    path = cell.path(root)
    numbers, timing = record_form(result)
    record = {"cell": cell.identity(), "config": cell.config, "result": numbers,
              "timing": timing,
              "features_file": features_path(path).name if features else None,
              "provenance": provenance}
    if features:
        buf = io.BytesIO()
        np.savez_compressed(buf, **{k: np.asarray(v, np.float32) for k, v in features.items()})
        storage.atomic_write_bytes(features_path(path), buf.getvalue())
        record[FEATURES_DIGEST] = hashlib.sha256(buf.getvalue()).hexdigest()
    storage.atomic_write_text(path, json.dumps(_sealed(record), indent=1) + "\n")
    return path


def provenance(*, command: str, budget: str, threads: int, wall_seconds: float,
               host: str = "", platform: dict | None = None) -> dict:
    """Where a cell's numbers came from.  ``platform`` (:func:`storage.platform_info`, taken
    in the process that ran the cell) says which machine kind they reproduce on bit for bit;
    records written before it was kept have none."""
    return {"command": command, "revision": storage.git_revision(), "budget": budget,
            "torch_threads": int(threads), "wall_seconds": float(wall_seconds), "host": host,
            "platform": platform if platform is not None else storage.platform_info(),
            "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}


def restore_hint(path) -> str:
    """How to get a cell file back: from git, or by running the cell again."""
    path = pathlib.Path(path)
    study = path.parent.parent.name
    return (f"restore it with `git checkout -- {path}` (a committed record), or delete it and "
            f"rerun the cell with `dc-lesson sweep {study}`")


def _read(path, what: str = "cell file") -> bytes:
    try:
        return storage.read_bytes(path, what, restore_hint(path))
    except storage.NotRegularFileError as e:
        raise CellError(str(e)) from None


# Text that may stand in a result where numbers do: the run's labels.  Everything else outside
# a ``config`` echo (the settings a study copies into its result) must be a number or null.
LABELS = frozenset({"task", "kind", "model", "feature", "modes"})
# Yes/no outcomes a result may hold as true or false: the modes study's mixture start,
# matched to plain BC or not (a bool anywhere else is refused: True would pass for 1).
FLAGS = frozenset({"matched"})


def _numbers_only(value, where: str, path, labels=LABELS) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            if k == "config":
                continue
            if k in labels and (isinstance(v, str) or (isinstance(v, list) and
                                                       all(isinstance(x, str) for x in v))):
                continue
            if k in FLAGS and isinstance(v, bool):
                continue
            _numbers_only(v, f"{where}.{k}", path, labels)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _numbers_only(v, f"{where}[{i}]", path, labels)
    elif value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
        raise CellError(f"cell file {path}: {where} is {value!r} ({type(value).__name__}) where "
                        f"a number (or null) belongs; {restore_hint(path)}")


def check_types(record: dict, path) -> None:
    """Every measure a reader takes from the record is a number (or null): ``result`` and
    ``timing`` but their labels and config echoes, and the provenance's wall time."""
    for key in ("result", "timing"):
        _numbers_only(record.get(key, {}), key, path)
    prov = record.get("provenance")
    if not isinstance(prov, dict):
        raise CellError(f"cell file {path}: provenance is missing; {restore_hint(path)}")
    _numbers_only({k: prov.get(k) for k in ("wall_seconds", "torch_threads")}, "provenance", path)
    for k in ("time", "budget"):
        if not isinstance(prov.get(k), str):
            raise CellError(f"cell file {path}: provenance.{k} is {prov.get(k)!r} where a "
                            f"string belongs; {restore_hint(path)}")


def _parse(path) -> dict:
    """The record's JSON, its name, config hash and types checked (not its digest)."""
    path = pathlib.Path(path)
    try:
        record = json.loads(_read(path))
        ident = record["cell"]
        row = ident["learner"] + (f"-{ident['variant']}" if ident["variant"] else "")
        expected = f"{row}__n{ident['n_demos']}__s{ident['seed']}__{ident['config_hash']}"
        ok = expected == path.stem and config_hash(record["config"]) == ident["config_hash"]
    except FileNotFoundError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise CellError(f"cell file {path} is unreadable ({e}); {restore_hint(path)}") from None
    if not ok:
        raise CellError(f"cell file {path} does not match its name or its config hash; "
                        f"{restore_hint(path)}")
    check_types(record, path)
    return record


def read_record(path) -> dict:
    """A cell record, checked: a regular file of valid JSON whose identity matches its file
    name, whose digest (if it has one) matches its content, and whose measures are numbers."""
    record = _parse(path)
    if DIGEST in record and record[DIGEST] != record_digest(record):
        raise CellError(f"cell file {path} does not match its sha256 (recorded "
                        f"{str(record[DIGEST])[:12]}..., content {record_digest(record)[:12]}"
                        f"...): it was edited by hand or damaged since the sweep wrote it; "
                        f"{restore_hint(path)}")
    return record


def read_features(path, record: dict | None = None) -> dict[str, np.ndarray]:
    """The ``.npz`` of mode features beside a cell record (no pickles), checked against the
    record's ``features_sha256`` when it has one (``record``: the record, if already read)."""
    fp = features_path(path)
    record = read_record(path) if record is None else record
    try:
        blob = _read(fp, "cell features file")
    except FileNotFoundError:
        raise CellError(f"{fp} is missing though its record names it; delete "
                        f"{pathlib.Path(path).name} and rerun the sweep") from None
    expected = record.get(FEATURES_DIGEST)
    if expected is not None and hashlib.sha256(blob).hexdigest() != expected:
        raise CellError(f"cell features file {fp} does not match the sha256 its record "
                        f"{pathlib.Path(path).name} gives: it was changed or damaged; "
                        f"{restore_hint(fp)}")
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as f:
            return {k: f[k] for k in f.files}
    except Exception as e:   # zip, CRC or header errors of a damaged file
        raise CellError(f"cell features file {fp} is unreadable ({type(e).__name__}: {e}); "
                        f"{restore_hint(fp)}") from None


def seal(root=None) -> tuple[int, int]:
    """Adds the digests to every record written before records carried them (a one-off
    migration: ``dc-lesson seal-cells``); returns ``(sealed, already sealed)``.  A record is
    checked first (name, hash, types, features readable), so a damaged one is refused, not
    sealed; a sealed record is verified, never sealed again."""
    sealed = already = 0
    for p in sorted(pathlib.Path(root or cells_root()).glob("*/*/*.json")):
        record = _parse(p)
        if DIGEST in record:
            read_record(p)
            already += 1
            continue
        if record.get("features_file"):
            read_features(p)
            record[FEATURES_DIGEST] = hashlib.sha256(_read(features_path(p))).hexdigest()
        storage.atomic_write_text(p, json.dumps(_sealed(record), indent=1) + "\n")
        sealed += 1
    return sealed, already


def is_done(cell: Cell, root=None) -> bool:
    """The cell's record exists with this config hash (and, if it names one, its features)."""
    path = cell.path(root)
    if not path.exists():
        return False
    record = read_record(path)
    return not record["features_file"] or features_path(path).exists()


def load(cell: Cell, root=None) -> tuple[dict, dict]:
    """``(record, features)`` of a finished cell (features ``{}`` when it keeps none)."""
    path = cell.path(root)
    record = read_record(path)
    return record, (read_features(path, record) if record["features_file"] else {})


def records(study: str, root=None) -> list[dict]:
    """Every record of a study on disk (any config), in a stable order."""
    base = pathlib.Path(root or cells_root()) / study
    return [read_record(p) for p in sorted(base.glob("*/*.json"))]


@dataclasses.dataclass(frozen=True)
class Study:
    """A grid of cells and the function that runs one.

    * ``cells(budget)`` lists the cells at a budget (references first, with ``stage`` 0);
    * ``run_cell(cell, needs)`` runs one, given ``needs``: the ``(record, features)`` of the
      cells it reads, in ``cell.needs`` order; it returns ``(result, features or None)``,
      JSON-able numbers and float32-able arrays, and must depend on nothing but the cell
      (one seed reaches everything, so a rerun gives the same numbers);
    * ``aggregate(records, cells)`` turns the finished cells into the study's tables;
    * ``result_file``: the aggregate's name under ``data/results/``.
    """
    name: str
    description: str
    cells: Callable
    run_cell: Callable
    aggregate: Callable | None = None
    result_file: str = ""

    def grid(self, budget) -> list[Cell]:
        """The study's cells with every cell they need, each once, stages in order."""
        out: dict[str, Cell] = {}

        def add(c: Cell):
            for n in c.needs:
                add(n)
            out.setdefault(f"{c.study}/{c.task}/{c.name}", c)
        for c in self.cells(budget):
            add(c)
        return sorted(out.values(), key=lambda c: c.stage)


__all__ = ["Cell", "CellError", "DIGEST", "FEATURES_DIGEST", "LABELS", "Study", "canonical",
           "cells_root", "check_types", "config_hash", "full_result", "is_done", "load",
           "make_cell", "merged", "provenance", "read_features", "read_record",
           "record_digest", "record_form", "records", "restore_hint", "seal", "split_timing",
           "write_record"]
