"""What every chapter does first: quiet dm_control's log, one torch thread, announce the budget
and how to change it."""

from __future__ import annotations

import logging
import textwrap

from dc_lesson import budget as _budget


# Printed under the budget's name in every chapter, at every budget: a reader in JupyterLab
# has no shell prompt in sight, so the note says how to switch from inside the notebook too.
# (budget.current() reads the variable when called, so %env before this cell takes effect.)
CHANGE_NOTE = (f"to change it: add a cell above this one with `%env {_budget.ENV_VAR}=lesson` "
               f"(or smoke, or paper) and Run > Run All Cells; or start JupyterLab as "
               f"`{_budget.ENV_VAR}=lesson jupyter lab book/`")


def start(smoke_note: str) -> _budget.Budget:
    """Returns the current budget after printing it, how to change it, and ``smoke_note`` (what
    the chapter's numbers mean at this budget) at ``smoke``."""
    import torch
    # dm_control logs through absl; its one notice here is MuJoCo's deprecation of the
    # `settotalmass` attribute in dm_control's own cheetah.xml, which is not ours to change.
    # (No tqdm filter: ipywidgets is a dependency, so the bars are widgets, and a missing
    # ipywidgets should show.)
    logging.getLogger("absl").setLevel(logging.ERROR)
    torch.set_num_threads(1)   # the machine's cores are shared; one thread also repeats exactly
    _tables()
    from dc_lesson.viz import legibility
    legibility.watch()         # a figure whose tick labels collide warns under its cell
    b = _budget.current()
    print(f"budget: {b.name} (one of {', '.join(_budget.PRESETS)})")
    print(_wrap(CHANGE_NOTE))
    if b.is_smoke:
        print(_wrap(f"smoke budget: {smoke_note}"))
    return b


def _tables() -> None:
    """pandas' display for a reader: a table cell is shown whole (the default cuts it at 50
    characters, mid-number, with an ellipsis); a wide table keeps its columns side by side."""
    import pandas as pd
    pd.set_option("display.max_colwidth", None)
    pd.set_option("display.width", 250)


def _wrap(text: str) -> str:
    # JupyterLab breaks a long output line at its edge, mid-word; break it between words.
    return textwrap.fill(text, width=88, break_long_words=False, break_on_hyphens=False,
                         subsequent_indent="  ")
