"""Where a run's time goes: named phases, timed only while someone records them.

The learners mark their phases (``with timing.phase("env"): ...``: collecting, stepping, the
updates, the flow fit, the reward); ``with timing.recording() as seconds:`` around a run fills
``seconds`` with each phase's total wall time.  Outside a recording a phase costs one function
call, so the marks stay in the code.  ``dc-lesson perf learners`` reads them.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import time

_RECORDER: dict | None = None


@contextlib.contextmanager
def phase(name: str):
    """Adds the block's wall time to phase ``name`` of the current recording (if any).
    Nested phases count in both: record disjoint phases where totals must add up."""
    if _RECORDER is None:
        yield
        return
    t0 = time.perf_counter()
    try:
        yield
    finally:
        _RECORDER[name] += time.perf_counter() - t0


@contextlib.contextmanager
def recording():
    """Records the phases of the block: yields a dict phase -> seconds, filled as it runs."""
    global _RECORDER
    old, _RECORDER = _RECORDER, collections.defaultdict(float)
    try:
        yield _RECORDER
    finally:
        _RECORDER = old


def timed(name: str):
    """A decorator: every call of the function is phase ``name``."""
    def wrap(fn):
        @functools.wraps(fn)
        def timed_fn(*args, **kwargs):
            if _RECORDER is None:
                return fn(*args, **kwargs)
            with phase(name):
                return fn(*args, **kwargs)
        return timed_fn
    return wrap


__all__ = ["phase", "recording", "timed"]
