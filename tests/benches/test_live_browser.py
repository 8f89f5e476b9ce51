"""The live view in a real headless browser: Playwright for Python driving the system's Chromium.

Where no Chromium (or no Playwright) can be had, these tests say so in one visible line of the test summary
(``tests/conftest.py``) instead of passing silently. The screenshot of the finished page is kept in
``test-artifacts/live-view.png`` (the README's picture is one of these).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests import REPO_ROOT, not_run_here
from tests.simbench import CLI, bench_variant, short_ten_step

ARTIFACTS = REPO_ROOT / "test-artifacts"
CHROMIUM_CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "chrome")
QUIET_FLAGS = [
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-default-apps",
    "--disable-extensions",
    "--no-first-run",
    "--no-default-browser-check",
    "--metrics-recording-only",
    "--no-sandbox",  # CI runs as root
]
RECORD_STEPS = """
window.__shown = [];
new MutationObserver((records) => {
  for (const r of records) for (const n of r.addedNodes) window.__shown.push(n.textContent);
}).observe(document, {subtree: true, childList: true});
"""


def _chromium() -> str | None:
    env = os.environ.get("TABLEBENCH_CHROMIUM")
    if env:
        return env if Path(env).is_file() else None
    for name in CHROMIUM_CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    from playwright.sync_api import sync_playwright  # a test dependency: its absence fails the suite

    exe = _chromium()
    if exe is None:
        not_run_here(
            "browser tests NOT RUN: no Chromium on this machine (apt-get install chromium; .ci/run does it), "
            "or set TABLEBENCH_CHROMIUM to a Chromium binary"
        )
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe, headless=True, args=QUIET_FLAGS)
        try:
            yield b
        finally:
            b.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_http(url: str, timeout: float = 120.0, proc: subprocess.Popen | None = None) -> None:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"the server process ended: {proc.stderr.read() if proc.stderr else ''}")
        try:
            with urllib.request.urlopen(url, timeout=2) as r:
                if r.status == 200:
                    return
        except OSError:
            time.sleep(0.1)
    raise AssertionError(f"{url} never answered")


def _page(browser: object, errors: list[str], console: list[str]):  # noqa: ANN202
    page = browser.new_page(viewport={"width": 1400, "height": 1000})  # type: ignore[attr-defined]
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: console.append(f"{m.type}: {m.text}") if m.type in ("error", "warning") else None)
    page.add_init_script(RECORD_STEPS)
    return page


def _procedure(tmp: Path, hold_s: float, warmup_s: float) -> Path:
    p = tmp / "short.yaml"
    p.write_text(short_ten_step(hold_s=hold_s, warmup_s=warmup_s, name="short"), encoding="utf-8")
    return p


def _printed_decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


def test_live_page_follows_a_run_to_its_result(browser: object, tmp_path: Path) -> None:
    """run --live: the step indicator shows every step in order, the page's final values equal calibration.json
    to the printed digits, no JavaScript error, and a screenshot that is not blank."""
    port = _free_port()
    bench = bench_variant(tmp_path, rate=100.0)
    out = tmp_path / "run"
    errors: list[str] = []
    console: list[str] = []
    page = _page(browser, errors, console)
    args = ["run", "--bench", str(bench), "--procedure", str(_procedure(tmp_path, 3, 10)), "--out", str(out)]
    args += ["--plain", "--seed", "11", "--live", f"127.0.0.1:{port}", "--live-linger", "120"]
    proc = subprocess.Popen(CLI + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)  # fmt: skip
    try:
        _wait_http(f"http://127.0.0.1:{port}/", proc=proc)
        page.goto(f"http://127.0.0.1:{port}/")
        page.wait_for_selector("#result-panel:not([hidden])", timeout=240_000)
        page.wait_for_timeout(800)  # one redraw of the plots
        shown = page.evaluate("window.__shown")
        steps = [e["data"] for e in _events(out) if e["event"] == "run"][0]["steps"]
        names = [s["name"] for s in steps]
        current = [t for t in shown if t in names]
        assert current == [n for n in names if n in current], "the step indicator went backwards"
        acquiring = [s["name"] for s in steps if s["kind"] in ("warmup", "hold", "spin")]
        assert set(acquiring) <= set(current), f"never shown as current: {sorted(set(acquiring) - set(current))}"
        states = page.eval_on_selector_all("#steps li", "els => els.map(e => e.dataset.state)")
        assert states == ["complete"] * len(steps)
        assert page.inner_text("#status") == "complete"
        _assert_final_values(page, out)
        assert page.inner_text("#verdict") == json.loads((out / "certificate.json").read_text())["verdict"]
        hrefs = page.eval_on_selector_all("#result-links a", "els => els.map(e => e.getAttribute('href'))")
        assert "files/calibration.json" in hrefs
        body = urllib.request.urlopen(f"http://127.0.0.1:{port}/files/calibration.json", timeout=5).read()
        assert body == (out / "calibration.json").read_bytes()
        ARTIFACTS.mkdir(exist_ok=True)
        shot = ARTIFACTS / "live-view.png"
        page.screenshot(path=str(shot), full_page=True)
        _assert_not_blank(shot)
        assert errors == [] and console == []
    finally:
        page.close()
        _stop(proc)


def test_live_page_recovers_after_the_server_drops_the_connection(browser: object, tmp_path: Path) -> None:
    """view follows a run going on in another process; its server is stopped mid-run and started again: the page
    reconnects (Last-Event-ID), loses nothing, draws nothing twice and reaches the result."""
    port = _free_port()
    bench = bench_variant(tmp_path, rate=250.0)
    out = tmp_path / "run"
    errors: list[str] = []
    console: list[str] = []
    run = subprocess.Popen(
        CLI + ["run", "--bench", str(bench), "--procedure", str(_procedure(tmp_path, 8, 30)), "--out", str(out),
               "--plain", "--seed", "12"],  # fmt: skip
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True,
    )  # fmt: skip
    views: list[subprocess.Popen] = []
    page = _page(browser, errors, console)
    try:
        t_end = time.monotonic() + 120
        while not (out / "live.jsonl").is_file() and time.monotonic() < t_end:
            time.sleep(0.05)
        views.append(_view(out, port))
        page.goto(f"http://127.0.0.1:{port}/")
        page.wait_for_function("document.querySelectorAll('#steps li[data-state=complete]').length >= 2",
                               timeout=120_000)  # fmt: skip
        _stop(views.pop())  # the server goes away: the stream ends, new connections are refused
        page.wait_for_function("document.getElementById('connection').dataset.state !== 'connected'", timeout=30_000)
        views.append(_view(out, port))
        page.wait_for_selector("#result-panel:not([hidden])", timeout=240_000)
        assert run.wait(timeout=120) == 0
        events = _events(out)
        assert page.get_attribute("#connection", "data-last-event") == str(events[-1]["id"])
        states = page.eval_on_selector_all("#steps li", "els => els.map(e => e.dataset.state)")
        assert states == ["complete"] * len(states) and states
        _assert_final_values(page, out)
        assert errors == []
        # while the server was away Chromium logs the refused reconnection attempts (network, not JavaScript)
        assert all("ERR_CONNECTION_REFUSED" in c or "/events" in c for c in console), console
    finally:
        page.close()
        for v in views:
            _stop(v)
        _stop(run)


def _view(folder: Path, port: int) -> subprocess.Popen:
    proc = subprocess.Popen(CLI + ["view", str(folder), "--live", f"127.0.0.1:{port}"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip
    _wait_http(f"http://127.0.0.1:{port}/", proc=proc)
    return proc


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def _events(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "live.jsonl").read_text(encoding="utf-8").splitlines()]


def _assert_final_values(page: object, folder: Path) -> None:
    """Every parameter on the result table equals calibration.json's value and u to the digits printed."""
    cal = json.loads((folder / "calibration.json").read_text(encoding="utf-8"))["parameters"]
    rows = page.eval_on_selector_all(  # type: ignore[attr-defined]
        "#result tbody tr",
        "els => els.map(e => [e.dataset.name, e.children[1].textContent, e.children[2].textContent])",
    )
    assert [r[0] for r in rows] == list(cal)
    for name, value, u in rows:
        for shown, true in ((value, cal[name]["display_value"]), (u, cal[name]["display_u"])):
            d = _printed_decimals(shown)
            assert abs(float(shown) - true) <= 0.5 * 10**-d * (1 + 1e-9), (name, shown, true)


def _assert_not_blank(png: Path) -> None:
    import matplotlib.image as mpimg

    img = mpimg.imread(str(png))
    assert img.shape[0] > 400 and img.shape[1] > 800
    flat = img[..., :3].reshape(-1, 3)
    assert float(flat.std()) > 0.05  # not one colour
    assert len(np.unique((flat[::97] * 255).astype(np.uint8), axis=0)) > 20  # text, plots and panels drawn
