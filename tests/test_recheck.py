"""``dc-lesson sweep STUDY --recheck N``: finished cells rerun in a sweep worker's environment
and compared with their records, number by number; a record changed by a last bit is caught,
a rerun on the same platform is identical, and nothing is written."""

import dataclasses
import json
import math

from dc_lesson import budget
from dc_lesson.experiments import cells, recheck, studies, sweep

TINY = dataclasses.replace(budget.get("smoke"), bc_demo_counts=(2,), sweep_seeds_reacher=1)
ONLY = ["task=reacher4", "learner=bc"]


def _sweep_here(root):
    """The selection's cells run in this process and recorded as a sweep records them."""
    for c in sweep.select(studies.get("bc_demos").grid(TINY), ONLY):
        out = sweep.execute(c, [cells.load(n, root) for n in c.needs])
        prov = cells.provenance(command="test", budget=TINY.name, threads=out["threads"],
                                wall_seconds=out["wall_seconds"], platform=out["platform"])
        cells.write_record(c, out["result"], out["features"], prov, root)


def test_a_rerun_is_identical_and_a_changed_record_is_caught(tmp_path):
    root = tmp_path / "cells"
    _sweep_here(root)
    before = {p: p.read_bytes() for p in root.rglob("*.json")}
    rows = recheck.recheck("bc_demos", TINY, ONLY, limit=5, root=root, log=lambda s: None)
    assert [r["cell"].split("/")[2].split("__")[0] for r in rows] == ["bc"]  # not the reference
    assert rows[0]["identical"] and rows[0]["same_platform"]
    # without --only: the learners' cells before the references (which select() lists first)
    first = recheck.recheck("bc_demos", TINY, (), limit=1, root=root, log=lambda s: None)
    assert first[0]["cell"].split("/")[2].startswith("bc__") and first[0]["identical"]
    assert {p: p.read_bytes() for p in root.rglob("*.json")} == before    # nothing written
    # One number of the record moved by a last bit: found, with its path and size.
    path = next(p for p in root.rglob("bc__*.json"))
    record = json.loads(path.read_text())
    key = next(k for k, v in record["result"].items() if isinstance(v, float) and v != 0)
    record["result"][key] = math.nextafter(record["result"][key], math.inf)
    # sealed again, as a sweep on another machine would have written it (an unsealed edit is
    # refused before any comparison: tests/test_integrity.py)
    record[cells.DIGEST] = cells.record_digest(record)
    path.write_text(json.dumps(record))
    row = recheck.recheck("bc_demos", TINY, ONLY, limit=1, root=root, log=lambda s: None)[0]
    assert not row["identical"] and row["numbers_differing"] == 1
    assert row["first"].startswith(f"/{key}:") and row["largest"][0] == f"/{key}"
    assert 0 < row["largest"][3] < 1e-12                     # relative to the number's size
    assert f"1 numbers differ, most at /{key}" in recheck.format_row(row)


def test_differences_walks_the_nesting():
    stored = {"a": [1.0, {"b": math.nan}], "c": "x", "d": [1, 2]}
    assert recheck.differences(stored, {"a": [1.0, {"b": math.nan}], "c": "x",
                                        "d": [1, 2]}) == []       # NaN equals NaN
    diffs = recheck.differences(stored, {"a": [1.5, {"b": math.nan}], "c": "y", "d": [1]})
    assert [d[0] for d in diffs] == ["/a[0]", "/c", "/d (length)"]
    assert recheck.differences({"a": 1}, {}) == [("/a", 1, "absent")]
