"""Claims the book's prose makes about stored results, checked against the result files."""

from dc_lesson import tasks
from dc_lesson.results import read_result


def test_chapter00_rollout_speed_claims_hold_in_the_stored_benchmark():
    rows = {r["task"]: r for r in read_result("bench_rollout.json")["rows"]}
    assert set(rows) == set(tasks.NAMES)
    for name, r in rows.items():
        assert r["rollout / dm_control"] > 1.0, name
        if tasks.spec(name).n_sub_steps >= 4:
            assert r["rollout / raw"] >= 0.5, name
