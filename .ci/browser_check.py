#!/usr/bin/env python
"""Open a chapter in JupyterLab in a real (headless) browser, run all its cells, and fail on
anything a reader would see as a problem.

    python .ci/browser_check.py all                          # every chapter: what .ci/run does
    python .ci/browser_check.py book/04_distributional_cloning.ipynb   # one chapter

What it does, in order:

1. copies ``book/`` and the jupytext configuration (``pyproject.toml``) to a temporary folder,
   so the run and the save below never touch the repository;
2. starts JupyterLab there on 127.0.0.1, a free port and a random token (``--allow-root``, no
   browser of its own), with ``DC_LESSON_BUDGET`` (``--budget``, else the environment's, else
   smoke) and ``MUJOCO_GL=egl`` in its
   environment so the kernel inherits them, and this checkout first on ``PYTHONPATH`` so the
   kernel imports this checkout's ``dc_lesson``;
3. drives Debian's ``/usr/bin/chromium`` with Playwright (no browser download): opens the
   notebook, clicks Run > Run All Cells, and waits until every cell has run and the kernel is
   idle (the Jupyter REST API's ``execution_state`` and the cells' ``[*]`` prompts);
4. fails (exit 1, one line per problem) on any error or stderr output (the pink boxes), a
   widget that did not render, a warning in any output (a figure whose tick labels collide is
   one: ``dc_lesson.viz.legibility``, which every chapter's ``notebook.start`` turns on), a
   figure the kernel sent that the page
   does not show, a cell that did not run, a table showing NaN / None / <NA>, a table cell cut
   short with an ellipsis, a figure drawn at less than 60% of its natural width (its labels
   become unreadable), a raw Python repr (a dict, an array, an object's address, a float of
   10 or more significant digits; the rules are in ``reader_rules.py``); and, after
   File > Save, on any change of the chapter's paired ``.py`` (a reader who only ran and saved
   must not get a git diff);
5. saves screenshots under ``outputs/`` of the repository: the whole notebook after the run,
   top to bottom (``browser_NAME.png``, continued in ``browser_NAME_2.png``, ...) and, on failure, the first problem (``browser_NAME_failure.png``);
   the server's log and the browser console go to ``outputs/browser_NAME_*.log``.

Exit status: 0 clean, 1 problems found, 2 the check itself could not run (no chromium, no
playwright, the server did not start, the run timed out).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

ROOT = pathlib.Path(__file__).resolve().parent.parent
# The rules on what a reader sees live beside this script (tested without a browser).
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from reader_rules import STDERR_MIME, dom_problems, model_problems  # noqa: E402
CHROMIUM = "/usr/bin/chromium"

# Lab settings of the run (a settings folder of its own, so a reader's settings cannot change
# the check): every cell stays in the page (no windowing), so every output can be read from
# it; no news or update pop-ups over the notebook.
LAB_SETTINGS = {
    "@jupyterlab/notebook-extension/tracker.jupyterlab-settings": {"windowingMode": "none"},
    "@jupyterlab/apputils-extension/notification.jupyterlab-settings": {
        "fetchNews": "false", "checkForUpdates": False},
}


class CheckError(RuntimeError):
    """The check could not be carried out (not a problem of the notebook)."""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def api(base: str, token: str, path: str, method: str = "GET", body=None, timeout=30):
    req = urllib.request.Request(
        f"{base}{path}", method=method,
        data=None if body is None else json.dumps(body).encode(),
        headers={"Authorization": f"token {token}", "Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=timeout) as r:
        raw = r.read()
    return json.loads(raw) if raw else None


def start_lab(workdir: pathlib.Path, port: int, token: str, log_path: pathlib.Path,
              budget: str) -> subprocess.Popen:
    settings = workdir / ".lab-settings"
    for rel, value in LAB_SETTINGS.items():
        (settings / rel).parent.mkdir(parents=True, exist_ok=True)
        (settings / rel).write_text(json.dumps(value))
    env = dict(os.environ)
    env["DC_LESSON_BUDGET"] = budget
    env.setdefault("MUJOCO_GL", "egl")
    env.setdefault("OMP_NUM_THREADS", "1")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env["JUPYTERLAB_SETTINGS_DIR"] = str(settings)
    env["JUPYTERLAB_WORKSPACES_DIR"] = str(workdir / ".lab-workspaces")
    cmd = [sys.executable, "-m", "jupyterlab", "--allow-root", "--no-browser",
           "--ServerApp.open_browser=False", "--ServerApp.ip=127.0.0.1",
           f"--ServerApp.port={port}", "--ServerApp.port_retries=0",
           f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={workdir}"]
    log = open(log_path, "w")
    # A session of its own, so the server and its kernel can be stopped together at the end.
    return subprocess.Popen(cmd, cwd=workdir, env=env, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)


def wait_for_server(proc: subprocess.Popen, base: str, token: str, log_path: pathlib.Path,
                    timeout: float = 90.0) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if proc.poll() is not None:
            raise CheckError(f"JupyterLab exited with code {proc.returncode}; its log:\n"
                             + log_path.read_text()[-3000:])
        try:
            api(base, token, "/api/status", timeout=5)
            return
        except (urllib.error.URLError, ConnectionError, OSError):
            time.sleep(0.5)
    raise CheckError(f"JupyterLab did not answer within {timeout:.0f} s; see {log_path}")


def stop_lab(proc: subprocess.Popen, base: str, token: str) -> None:
    if proc.poll() is None:
        try:
            api(base, token, "/api/shutdown", method="POST", timeout=10)
            proc.wait(timeout=20)
        except (urllib.error.URLError, OSError, subprocess.TimeoutExpired):
            pass
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)   # the group this script started, nothing else
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def kernel_state(base: str, token: str, nb_path: str) -> str | None:
    for s in api(base, token, "/api/sessions"):
        if s.get("path") == nb_path and s.get("kernel"):
            return api(base, token, f"/api/kernels/{s['kernel']['id']}")["execution_state"]
    return None


PROMPTS_JS = """() => Array.from(document.querySelectorAll(
    '.jp-NotebookPanel:not(.lm-mod-hidden) .jp-CodeCell .jp-InputArea-prompt'))
    .map(e => e.textContent.trim())"""


def run_all_and_wait(page, base, token, nb_path, timeout) -> tuple[int, int]:
    """Clicks Run > Run All Cells; returns (code cells run, code cells) once done."""
    page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(r"^Run$")).click()
    page.locator(".lm-Menu-itemLabel", has_text=re.compile(r"^Run All Cells$")).click()
    t0, quiet = time.monotonic(), 0
    while time.monotonic() - t0 < timeout:
        time.sleep(1.0)
        prompts = page.evaluate(PROMPTS_JS)
        ran = sum(bool(re.fullmatch(r"\[\d+\]:", p)) for p in prompts)
        running = any(p == "[*]:" for p in prompts)
        state = kernel_state(base, token, nb_path)
        # Idle with nothing queued, twice in a row: a kernel is briefly idle between cells.
        quiet = quiet + 1 if (state == "idle" and not running and ran) else 0
        if quiet >= 3:
            return ran, len(prompts)
    raise CheckError(f"the cells had not finished after {timeout:.0f} s")


# Every output area of the open notebook, as what the reader sees: its MIME type, its text,
# and whether it holds a figure, a progress widget or a widget that failed.
OUTPUTS_JS = """() => Array.from(document.querySelectorAll(
    '.jp-NotebookPanel:not(.lm-mod-hidden) .jp-OutputArea-output')).map((e, i) => {
      e.setAttribute('data-check-index', String(i));
      const cell = e.closest('.jp-Cell');
      const cells = Array.from(cell.parentElement.children).filter(c => c.classList.contains('jp-Cell'));
      return {index: i, cell: cells.indexOf(cell), mime: e.getAttribute('data-mime-type') || '',
              text: e.innerText || '',
              images: e.querySelectorAll('img, canvas, svg.main-svg').length,
              widget: e.querySelectorAll('.jupyter-widgets').length > 0,
              progress: e.querySelectorAll('.jupyter-widgets [class*="progress"], progress').length,
              widgetError: /Error displaying widget|Loading widget/.test(e.innerText || ''),
              cells: Array.from(e.querySelectorAll('table td, table th')).map(c => c.innerText.trim()),
              imgs: Array.from(e.querySelectorAll('img')).map(im => ({drawn: im.clientWidth,
                                                                       natural: im.naturalWidth}))};
    })"""


SCROLLER = ".jp-NotebookPanel:not(.lm-mod-hidden) .jp-WindowedPanel-outer"


def full_notebook_screenshot(page, path: pathlib.Path, sheet_height: int = 20000) -> list:
    """The whole notebook, top to bottom. The Lab scrolls inside its notebook panel, so a
    page screenshot shows one screen of it: the panel is scrolled a screen at a time and the
    pieces are stacked into sheets of at most ``sheet_height`` pixels (``path`` is the first;
    a long chapter continues in ``NAME_2.png``, ``NAME_3.png``, ...). Returns the files."""
    import io

    from PIL import Image
    scroller = page.locator(SCROLLER).first
    if not scroller.count():
        page.screenshot(path=str(path), full_page=True)
        return
    view = page.evaluate(f"() => document.querySelector('{SCROLLER}').clientHeight")
    pieces, covered, y = [], 0, 0
    while True:
        top = page.evaluate(f"y => {{ const s = document.querySelector('{SCROLLER}'); "
                            "s.scrollTop = y; return s.scrollTop; }", y)
        time.sleep(0.3)
        img = Image.open(io.BytesIO(scroller.screenshot()))
        scale = img.height / view                       # the device pixel ratio
        skip = max(0, covered - top)                    # the last piece overlaps the one before
        pieces.append(img.crop((0, int(skip * scale), img.width, img.height)))
        covered = top + view
        if top < y or covered >= page.evaluate(
                f"() => document.querySelector('{SCROLLER}').scrollHeight"):
            break
        y = covered
    sheets, current = [], []
    for piece in pieces:
        if current and sum(p.height for p in current) + piece.height > sheet_height:
            sheets.append(current)
            current = []
        current.append(piece)
    sheets.append(current)
    files = []
    for k, group in enumerate(sheets):
        sheet = Image.new("RGB", (group[0].width, sum(p.height for p in group)), "white")
        offset = 0
        for piece in group:
            sheet.paste(piece, (0, offset))
            offset += piece.height
        out = path if k == 0 else path.with_name(f"{path.stem}_{k + 1}{path.suffix}")
        sheet.save(out)
        files.append(out)
    return files


def check(notebook: pathlib.Path, out_dir: pathlib.Path, budget: str, timeout: float,
          headed: bool) -> list[str]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        raise CheckError("playwright is not installed: pip install playwright (the browser is "
                         f"Debian's {CHROMIUM}: apt-get install -y chromium)")
    if not pathlib.Path(CHROMIUM).exists():
        raise CheckError(f"{CHROMIUM} is missing: apt-get install -y chromium")
    notebook = notebook.resolve()
    book = ROOT / "book"
    if notebook.parent != book or notebook.suffix != ".ipynb" or not notebook.exists():
        raise CheckError(f"{notebook} is not a chapter notebook book/NN_name.ipynb")
    stem = notebook.stem
    out_dir.mkdir(parents=True, exist_ok=True)
    shots = {"run": out_dir / f"browser_{stem}.png", "failure": out_dir / f"browser_{stem}_failure.png"}
    shots["failure"].unlink(missing_ok=True)

    work = pathlib.Path(tempfile.mkdtemp(prefix="dc-lesson-browser-"))
    proc = None
    try:
        shutil.copytree(book, work / "book", ignore=shutil.ignore_patterns(
            "__pycache__", ".ipynb_checkpoints"))
        shutil.copy2(ROOT / "pyproject.toml", work / "pyproject.toml")   # [tool.jupytext]
        port, token = free_port(), secrets.token_hex(16)
        base = f"http://127.0.0.1:{port}"
        server_log = out_dir / f"browser_{stem}_server.log"
        phases, t_phase = {}, time.monotonic()

        def phase(name):
            nonlocal t_phase
            phases[name] = time.monotonic() - t_phase
            t_phase = time.monotonic()

        proc = start_lab(work, port, token, server_log, budget)
        wait_for_server(proc, base, token, server_log)
        phase("server")
        nb_path = f"book/{notebook.name}"
        console: list[str] = []
        problems: list[str] = []
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=not headed,
                                        args=["--no-sandbox", "--disable-dev-shm-usage"])
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.on("console", lambda m: console.append(f"{m.type}: {m.text}"))
            try:
                page.goto(f"{base}/lab/tree/{nb_path}?token={token}", timeout=120_000)
                page.wait_for_selector(".jp-NotebookPanel .jp-Cell", timeout=120_000)
                # The kernel starts with the notebook; run only once it is up.
                t0 = time.monotonic()
                while kernel_state(base, token, nb_path) != "idle":
                    dialog = page.locator(".jp-Dialog")
                    if dialog.count() and dialog.first.is_visible():
                        # A chapter whose kernelspec Lab cannot start asks the reader to pick
                        # one: a problem, but the rest of the check can go on with the default.
                        problems.append("opening it asks for a kernel: "
                                        + " ".join(dialog.first.inner_text().split())[:200])
                        dialog.first.locator(".jp-mod-accept").click()
                    if time.monotonic() - t0 > 120:
                        raise CheckError("the notebook's kernel did not start within 120 s")
                    time.sleep(0.5)
                phase("open")
                ran, n_code = run_all_and_wait(page, base, token, nb_path, timeout)
                phase("run")
                time.sleep(2.0)   # the last outputs and widgets render
                outputs = page.evaluate(OUTPUTS_JS)
                found = dom_problems(outputs)
                problems += [msg for _, msg in found]
                if ran < n_code:
                    problems.append(f"only {ran} of {n_code} code cells ran")
                n_images = sum(o["images"] > 0 for o in outputs)
                n_bars = sum(o["progress"] > 0 for o in outputs)
                n_widgets = sum(o["widget"] for o in outputs)
                print(f"  {ran} of {n_code} code cells ran; {len(outputs)} outputs: "
                      f"{n_images} with a figure, {n_bars} progress bars "
                      f"({n_widgets} widget outputs), "
                      f"{sum(o['mime'] == STDERR_MIME for o in outputs)} stderr or error boxes")
                if found:
                    el = page.locator(f'[data-check-index="{found[0][0]}"]')
                    el.scroll_into_view_if_needed()
                    page.screenshot(path=str(shots["failure"]))
                # Save as a reader would (File > Save Notebook), then read back what was saved.
                page.locator(".lm-MenuBar-itemLabel", has_text=re.compile(r"^File$")).click()
                page.locator(".lm-Menu-itemLabel",
                             has_text=re.compile(r"^Save Notebook$")).click()
                t0 = time.monotonic()
                while page.locator(".jp-NotebookPanel .jp-mod-dirty").count() or \
                        page.locator(".lm-TabBar-tab.jp-mod-dirty").count():
                    if time.monotonic() - t0 > 30:
                        raise CheckError("the notebook was not saved within 30 s")
                    time.sleep(0.5)
                time.sleep(1.0)
                saved = api(base, token, f"/api/contents/{nb_path}?content=1")["content"]
                # The run as artefacts: the executed notebook and what the page showed.
                (out_dir / f"browser_{stem}.ipynb").write_text(json.dumps(saved, indent=1))
                (out_dir / f"browser_{stem}_outputs.json").write_text(json.dumps(
                    [{k: o[k] for k in ("cell", "mime", "images", "widget", "progress", "text")}
                     for o in outputs], indent=1))
                problems += [f"saved notebook: {m}" for m in model_problems(saved)]
                # Every figure the kernel sent is on the page.
                sent = sum(any(k.startswith("image/") for k in out.get("data", {}))
                           for c in saved["cells"] for out in c.get("outputs", []))
                shown = sum(o["mime"].startswith("image/") and o["images"] > 0 for o in outputs)
                if shown < sent:
                    problems.append(f"the kernel sent {sent} figures, the page shows {shown}")
                py = notebook.with_suffix(".py")
                saved_py = work / "book" / py.name
                if saved_py.read_bytes() != py.read_bytes():
                    diff = subprocess.run(["git", "diff", "--no-index", "--", str(py),
                                           str(saved_py)], capture_output=True, text=True).stdout
                    problems.append(f"saving in the Lab changed {py.relative_to(ROOT)}:\n"
                                    + "\n".join(diff.splitlines()[:40]))
                full_notebook_screenshot(page, shots["run"])
                phase("save and screenshots")
                print("  seconds: " + ", ".join(f"{k} {v:.0f}" for k, v in phases.items()))
            except Exception:
                page.screenshot(path=str(shots["failure"]))
                raise
            finally:
                (out_dir / f"browser_{stem}_console.log").write_text("\n".join(console) + "\n")
                browser.close()
        if problems and not shots["failure"].exists():
            shutil.copy2(shots["run"], shots["failure"])
        return problems
    finally:
        if proc is not None:
            stop_lab(proc, base, token)
        shutil.rmtree(work, ignore_errors=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("notebooks", nargs="*", default=[str(ROOT / "book" / "00_tour.ipynb")],
                    help="chapters, book/NN_name.ipynb (default: book/00_tour.ipynb); "
                         "'all' for every chapter")
    ap.add_argument("--budget", default=os.environ.get("DC_LESSON_BUDGET", "smoke"),
                    help="DC_LESSON_BUDGET of the kernel (default: the environment's "
                         "DC_LESSON_BUDGET, else smoke)")
    ap.add_argument("--timeout", type=float, default=600.0,
                    help="seconds the cells may take (default 600)")
    ap.add_argument("--out", default=str(ROOT / "outputs"), help="folder of the screenshots")
    ap.add_argument("--headed", action="store_true", help="show the browser (needs a display)")
    args = ap.parse_args(argv)
    names = args.notebooks
    if names == ["all"]:
        names = [str(p) for p in sorted((ROOT / "book").glob("[0-9][0-9]_*.ipynb"))]
    worst = 0
    for name in names:
        # a chapter that could not be checked (2) is tried once more: a slow start is not a
        # fault of the chapter; a problem a reader would see (1) is final
        rc = check_one(pathlib.Path(name), args)
        if rc == 2:
            print("browser check could not run; trying once more")
            rc = check_one(pathlib.Path(name), args)
        worst = max(worst, rc)
    return worst


def check_one(nb: pathlib.Path, args) -> int:
    t0 = time.monotonic()
    print(f"browser check: {nb} in JupyterLab, chromium at {CHROMIUM}, budget {args.budget}")
    try:
        problems = check(nb, pathlib.Path(args.out), args.budget, args.timeout, args.headed)
    except Exception as e:   # CheckError, or Playwright's timeout before any cell ran
        if not isinstance(e, CheckError) and type(e).__name__ != "TimeoutError":
            raise
        print(f"browser check could not run: {e} ({time.monotonic() - t0:.0f} s)",
              file=sys.stderr)
        return 2
    seconds = time.monotonic() - t0
    shots = f"screenshots in {pathlib.Path(args.out)}"
    if problems:
        print(f"browser check FAILED on {nb.name} ({len(problems)} problems, {seconds:.0f} s; "
              f"{shots}):", file=sys.stderr)
        for msg in problems:
            print(f"  - {msg}", file=sys.stderr)
        return 1
    print(f"browser check passed: {nb.name}, no error, stderr, warning, missing value, cut "
          f"cell, shrunken figure or raw repr ({seconds:.0f} s; {shots})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
