"""What a reader of a chapter must not see, as rules on its rendered outputs (no browser here:
``browser_check.py`` gathers the outputs from the page and the saved notebook and applies
these; ``tests/test_browser_check.py`` tests them on constructed outputs).

An output, as the page gives it: ``{"index", "cell", "mime", "text", "cells", "imgs", ...}``
(``text`` what the reader sees, ``cells`` a table's cells, ``imgs`` each image's drawn and
natural width)."""

from __future__ import annotations

import re

STDERR_MIME = "application/vnd.jupyter.stderr"
# A warning in an output cell, whatever printed it: Python's warnings (UserWarning,
# TqdmWarning, ...), absl's "W0101 ... settotalmass is deprecated" lines, or a "warning:" text.
WARNING_RE = re.compile(r"warning|^W\d{4} \d\d:\d\d", re.IGNORECASE | re.MULTILINE)

# What a table must not show a reader: a missing value as NaN/None/<NA>, or a value cut short
# by pandas' display.max_colwidth (an ellipsis at its end).
# (case matters: lowercase "none" is the mode-share class of episodes that arrived nowhere)
MISSING_CELLS = {"NaN", "nan", "None", "<NA>", "NaT"}
MIN_DRAWN_FRACTION = 0.6   # a figure drawn at less than this of its width has unreadable labels

# A float as Python's repr prints it: a float32 widened to a float64 (-0.4000000059604645) or
# float arithmetic's last bits (0.30000000000000004). No measure here has ten significant
# digits, and they bury the two or three that matter. The lookarounds leave versions (3.17.0),
# addresses and words with digits alone; integers are not floats.
FLOAT_RE = re.compile(r"(?<![\w.])\d*\.\d+(?:[eE][-+]?\d+)?(?![\w.]*\d)")
MAX_SIGNIFICANT = 9
# Other reprs Python prints when nobody formatted the value: (what it is, its pattern)
REPR_RES = [
    ("a dict", re.compile(r"\{\s*(['\"])[^'\"\n]{0,80}\1\s*:")),
    ("an object's address", re.compile(r"\bat 0x[0-9a-fA-F]{4,}>")),
    ("a NumPy or torch array", re.compile(r"\b(?:array|tensor)\(")),
    ("a NumPy scalar", re.compile(r"\bnp\.(?:float|int|uint|bool|str)\w*\(")),
    ("a dataclass", re.compile(r"\b[A-Z][A-Za-z0-9]*\([a-z_][a-z0-9_]*=")),
    ("a matplotlib object", re.compile(r"\bText\(-?\d|<Figure size \d|<Axes: ")),
]


def table_problems(cells) -> list[str]:
    problems = []
    missing = sorted({c for c in cells if c in MISSING_CELLS})
    if missing:
        problems.append(f"a table shows missing values as {', '.join(missing)}")
    cut = [c for c in cells if c.endswith("...") or c.endswith("\u2026")]
    if cut:
        problems.append(f"{len(cut)} table cells cut short with an ellipsis, e.g. {cut[0][-60:]!r}")
    return problems


def image_problems(imgs) -> list[str]:
    small = [im for im in imgs if im["natural"] and im["drawn"] / im["natural"] < MIN_DRAWN_FRACTION]
    return [f"a figure drawn at {im['drawn'] / im['natural']:.0%} of its width "
            f"({im['natural']} px wide): make it narrower" for im in small[:1]]


def _significant(number: str) -> int:
    return len(re.split(r"[eE]", number)[0].replace(".", "").lstrip("0"))


def repr_problems(text: str) -> list[str]:
    """Raw Python reprs in what the reader sees: one problem per kind, with an example."""
    problems = []
    long = [m.group() for m in FLOAT_RE.finditer(text) if _significant(m.group()) > MAX_SIGNIFICANT]
    if long:
        problems.append(f"a raw float repr ({len(long)} numbers of 10 or more significant digits, "
                        f"e.g. {long[0]}): format it (f'{{x:.3f}}')")
    for kind, pattern in REPR_RES:
        m = pattern.search(text)
        if m:
            around = " ".join(text[max(0, m.start() - 20):m.end() + 40].split())
            problems.append(f"a raw Python repr of {kind} ({around!r}): print it for a reader "
                            "(a sentence or a table)")
    return problems


def dom_problems(outputs) -> list[tuple[int, str]]:
    problems = []
    for o in outputs:
        snippet = " ".join(o["text"].split())[:300]
        where = f"cell {o['cell'] + 1}"
        for msg in table_problems(o.get("cells", [])) + image_problems(o.get("imgs", [])):
            problems.append((o["index"], f"{where}: {msg}"))
        if o["mime"] == STDERR_MIME:
            problems.append((o["index"], f"{where}: error or stderr output: {snippet!r}"))
            continue   # a traceback is full of reprs: the stderr problem says it all
        for msg in repr_problems(o["text"]):
            problems.append((o["index"], f"{where}: {msg}"))
        if o["widgetError"]:
            problems.append((o["index"], f"{where}: a widget did not render: {snippet!r}"))
        elif WARNING_RE.search(o["text"]):
            problems.append((o["index"], f"{where}: warning text in an output: {snippet!r}"))
    return problems


def model_problems(nb: dict) -> list[str]:
    """The saved notebook's outputs, read back through the contents API: the same checks on
    what the kernel sent, including anything the page did not show."""
    problems = []
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    for i, cell in enumerate(nb["cells"]):
        for out in cell.get("outputs", []):
            kind = out["output_type"]
            if kind == "error":
                problems.append(f"cell {i + 1}: {out['ename']}: {out['evalue']}"[:300])
                continue
            if kind == "stream":
                text = "".join(out["text"])
                if out["name"] == "stderr":
                    problems.append(f"cell {i + 1}: stderr: {' '.join(text.split())[:300]!r}")
                    continue
            else:
                text = "".join(out.get("data", {}).get("text/plain", ""))
            if WARNING_RE.search(text):
                problems.append(f"cell {i + 1}: warning: {' '.join(text.split())[:300]!r}")
    if not any(c.get("execution_count") for c in code):
        problems.append("the saved notebook has no executed cell")
    return problems
