"""What every chapter does first: quiet the noise, one torch thread, announce the budget."""

from __future__ import annotations

import logging
import warnings

from dc_lesson import budget as _budget


def start(smoke_note: str) -> _budget.Budget:
    """Returns the current budget after printing it (and ``smoke_note`` at ``smoke``)."""
    import torch
    warnings.filterwarnings("ignore", message="IProgress not found")   # tqdm without ipywidgets
    logging.getLogger("absl").setLevel(logging.ERROR)                  # dm_control's notices
    torch.set_num_threads(1)   # the machine's cores are shared; one thread also repeats exactly
    b = _budget.current()
    print(f"budget: {b.name}")
    if b.is_smoke:
        print(f"smoke budget: {smoke_note}")
    return b
