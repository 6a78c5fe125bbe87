"""Progress bars, written once for the whole library.

Every loop that takes more than a moment (training, rollouts, sweeps) shows a bar through
:func:`bar`: a widget in JupyterLab (tqdm's notebook bar, with ipywidgets installed), a live
line in a terminal, and in a log file (output that is not a terminal) a few plain lines instead
of hundreds of carriage-return updates.
"""

from __future__ import annotations

import sys


def _interactive() -> bool:
    try:
        return sys.stderr.isatty() or "ipykernel" in sys.modules
    except (AttributeError, ValueError):
        return False


def bar(iterable=None, *, total=None, initial: int = 0, desc: str = "", unit: str = "it",
        enabled: bool = True, **kwargs):
    """A tqdm bar; ``enabled=False`` gives a silent one.  Outside a terminal or a notebook the
    bar prints at most every 30 s, so a log gets a handful of lines per bar."""
    from tqdm.auto import tqdm
    if not _interactive():
        kwargs.setdefault("mininterval", 30.0)
        kwargs.setdefault("ascii", True)
    return tqdm(iterable, total=total, initial=initial, desc=desc, unit=unit,
                disable=not enabled, **kwargs)


__all__ = ["bar"]
