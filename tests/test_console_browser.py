"""The console in a real browser (Debian's chromium, driven by Playwright), against a running
daemon on the small simulated bench: log in, aim, scan, look, go live, by mouse and by keyboard,
with no console error on any page."""

from __future__ import annotations

import re
import shutil
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from tests.conftest import small_config_data
from tests.loopback import daemon_http
from tests.test_daemon import KEY, Daemon, _config

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
playwright = pytest.importorskip(
    "playwright.sync_api", reason="Playwright for Python is not installed (pip install -e '.[test]')"
)
pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium here: `apt-get install chromium` (.ci/run installs it)"
)
PAGES = ("rig", "aim", "scan", "live", "scans", "calibration", "rings", "recognition")


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    tmp = tmp_path_factory.mktemp("console")
    d = Daemon(_config(tmp, small_config_data(), max_queue=4), tmp / "daemon.log")
    yield d
    d.stop()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with playwright.sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield chromium
        chromium.close()


class Console:
    """One browser tab on the console, collecting every console error and uncaught exception."""

    def __init__(self, browser: Any, daemon: Daemon) -> None:
        self.url = daemon.url
        self.page = browser.new_page(viewport={"width": 1280, "height": 900})
        self.errors: list[str] = []
        self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        self.page.on("pageerror", lambda e: self.errors.append(f"uncaught: {e}"))

    def log_in(self, key: str = KEY) -> None:
        self.page.goto(self.url + "/")
        self.page.fill("input[name=key]", key)
        self.page.press("input[name=key]", "Enter")

    def until(self, script: str, timeout_s: float = 30.0) -> Any:
        """Poll `script` (a function) until it returns something true. Playwright's wait_for_function
        evaluates strings in the page, which the console's CSP (no eval) forbids; evaluate does not."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            value = self.page.evaluate(script)
            if value:
                return value
            time.sleep(0.1)
        raise AssertionError(f"not within {timeout_s} s: {script}")

    def go(self, page: str) -> None:
        self.page.goto(f"{self.url}/#/{page}")
        self.page.wait_for_selector("main h1")


@pytest.fixture
def console(browser: Any, daemon: Daemon) -> Iterator[Console]:
    tab = Console(browser, daemon)
    tab.log_in()
    tab.page.wait_for_selector("h1:has-text('Rig')")
    yield tab
    tab.page.close()


def test_a_wrong_key_is_refused_and_the_right_one_logs_in_and_out(browser: Any, daemon: Daemon) -> None:
    tab = Console(browser, daemon)
    tab.log_in("this is not the key, sorry")
    tab.until("() => document.querySelector('form.login .error').textContent.includes('not valid')")
    assert tab.page.locator("h1").inner_text() == "Log in"
    assert all("403" in e for e in tab.errors)  # the refused login is the one failed request
    tab.errors.clear()
    tab.page.fill("input[name=key]", KEY)
    tab.page.press("input[name=key]", "Enter")
    tab.page.wait_for_selector("h1:has-text('Rig')")
    cookie = next(c for c in tab.page.context.cookies() if c["name"] == "slrig_session")
    assert cookie["httpOnly"] and cookie["sameSite"] == "Strict" and KEY not in cookie["value"]
    assert tab.page.evaluate("() => document.cookie") == ""  # the page's scripts cannot read it
    tab.page.click("#logout")
    tab.page.wait_for_selector("h1:has-text('Log in')")
    tab.page.reload()
    tab.page.wait_for_selector("h1:has-text('Log in')")  # the session is gone, not just the page
    assert tab.errors == []
    tab.page.close()


def test_every_page_loads_without_a_console_error(console: Console) -> None:
    console.until("() => document.body.textContent.includes('This machine has what the config needs.')")  # doctor
    for name in PAGES:
        console.go(name)
        time.sleep(0.5)  # the page's first requests answered
    console.go("viewer")
    console.page.goto(console.url + "/docs")
    console.page.wait_for_selector(".swagger-ui .opblock", timeout=20_000)  # Swagger UI drew from local files
    assert console.errors == []


FRAME = "document.querySelector('canvas.frame').dataset.frame"


def test_aim_frames_change_and_an_exposure_change_reaches_the_simulated_camera(
    console: Console, daemon: Daemon
) -> None:
    console.go("aim")
    console.page.click("text=Show pattern")
    first = int(console.until(f"() => Number({FRAME}) > 0 && {FRAME}"))
    later = int(console.until(f"() => Number({FRAME}) > {first} + 5 && {FRAME}"))
    assert later > first
    console.page.fill("input[name=exposure_us]", "3500")
    console.page.click("text=Set")
    console.until("() => document.querySelector('canvas.frame').dataset.exposure === '3500'")
    cameras = daemon_http.get(f"{daemon.url}/v1/cameras").json()
    assert cameras[0]["exposure_us"] == 3500  # the daemon's camera, not the page's idea of it
    assert "frames/s" in console.page.locator(".figures").inner_text()
    console.page.click("text=Dark")
    console.until("() => document.querySelector('.state').textContent === 'off'")
    assert console.errors == []


def _canvas_pixels(console: Console, selector: str) -> np.ndarray:
    import cv2

    png = console.page.locator(selector).screenshot()
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


def test_a_scan_started_from_the_scan_page_reaches_done_and_the_viewer_draws_it(console: Console) -> None:
    console.go("scan")
    console.page.select_option("select[name=codec]", "gray")
    console.page.fill("input[name=label]", "from the browser")
    console.page.click("text=Start scan")
    console.until("() => document.querySelector('section[data-state]')?.dataset.state === 'done'", 180)
    assert "rms against the truth" in console.page.locator(".result").inner_text()
    console.page.click("text=Open in the 3D viewer")
    points = int(console.until("() => document.querySelector('canvas.viewer')?.dataset.points", 60))
    assert points > 10_000
    image = _canvas_pixels(console, "canvas.viewer")
    background = np.array([28, 23, 18])  # BGR of the viewer's clear colour (0.07, 0.09, 0.11)
    drawn = np.abs(image.astype(int) - background).sum(axis=2) > 24
    assert drawn.mean() > 0.05  # the cloud covers part of the canvas
    console.page.select_option("select[name=mode]", "depth")
    depth = _canvas_pixels(console, "canvas.viewer")
    assert np.abs(depth.astype(int) - image.astype(int)).mean() > 2  # another colouring, drawn
    assert console.errors == []


def test_the_scan_page_scans_with_hdr_and_says_at_which_exposures(console: Console) -> None:
    console.go("scan")
    page = console.page
    page.check("input[name=adaptive]")  # a planned ring scan takes them too: only the codec is the plan's
    assert page.is_disabled("select[name=codec]")
    assert page.is_enabled("select[name=hdr]") and page.is_enabled("input[name=adaptive_projection]")
    page.uncheck("input[name=adaptive]")
    page.select_option("select[name=codec]", "gray")
    page.fill("input[name=exposure]", "auto")
    page.select_option("select[name=hdr]", "2")
    page.click("text=Start scan")
    console.until("() => document.querySelector('section[data-state]')?.dataset.state === 'done'", 180)
    shown = page.locator(".result").inner_text()
    assert "exposure" in shown and "hdr · " in shown and shown.count(" ms") >= 1
    assert console.errors == []


def test_the_live_page_updates(console: Console) -> None:
    console.go("live")
    console.page.click("text=Start")
    first = int(console.until("() => document.querySelector('img.depth')?.dataset.sequence", 60))
    console.until(f"() => Number(document.querySelector('img.depth').dataset.sequence) > {first}", 60)
    shown = console.page.locator(".figures").inner_text()
    assert "sequences/s" in shown and re.search(r"· \d+ dropped", shown)  # whole sequences fallen behind on
    console.page.click("text=Stop")
    console.until("() => document.querySelector('.state').textContent === 'off'")
    assert console.errors == []


REACHABLE = """() => [...document.querySelectorAll('a[href], button, input, select, textarea, [tabindex="0"]')]
  .filter((e) => !e.disabled && e.offsetParent !== null && !e.closest('[hidden]'))
  .map((e) => e.outerHTML.slice(0, 80))"""
# Tab starts from the page's top: a blur() leaves the starting point where the focus was (Firefox
# keeps it there), so a span before everything, out of the tab order, takes the focus first.
FROM_THE_TOP = """(() => { let s = document.getElementById('tab-start');
  if (!s) { s = document.createElement('span'); s.id = 'tab-start'; s.tabIndex = -1; document.body.prepend(s); }
  s.focus(); return true; })()"""


def test_every_control_of_every_page_is_reached_by_tab(console: Console) -> None:
    page = console.page
    for name in PAGES:
        console.go(name)
        time.sleep(0.5)
        controls = page.evaluate(REACHABLE)
        page.evaluate(FROM_THE_TOP)
        reached = set()
        for _ in range(len(controls) + 5):
            page.keyboard.press("Tab")
            reached.add(page.evaluate("() => document.activeElement.outerHTML.slice(0, 80)"))
        missing = [c for c in controls if c not in reached]
        assert not missing, f"{name}: not reached by Tab: {missing}"
    assert console.errors == []


def test_every_page_can_be_reached_and_used_by_keyboard(console: Console) -> None:
    page = console.page
    focused: Callable[[], str] = lambda: page.evaluate("() => document.activeElement.textContent.trim()")  # noqa: E731
    page.keyboard.press("Tab")  # from the document: the brand link first
    reached = []
    for _ in range(12):
        page.keyboard.press("Tab")
        reached.append(focused())
        if focused() == "Scans":
            break
    assert reached[:4] == ["Rig", "Aim & expose", "Scan", "Live"]
    page.keyboard.press("Enter")
    page.wait_for_selector("h1:has-text('Scans')")
    console.go("scan")
    page.focus("select[name=codec]")
    page.keyboard.press("Tab")
    assert page.evaluate("() => document.activeElement.name") == "label"
    for _ in range(20):  # on to the start button, past every field
        page.keyboard.press("Tab")
        if focused() == "Start scan":
            break
    assert focused() == "Start scan"
    outline = page.evaluate("() => getComputedStyle(document.activeElement).outlineStyle")
    assert outline != "none"  # where the focus is can be seen
    assert console.errors == []


def test_a_calibration_from_its_page_shows_its_report(console: Console) -> None:
    console.go("calibration")
    console.page.fill("input[name=views]", "6")
    console.page.click("button:text-is('Calibrate')")
    console.until("() => document.querySelector('section[data-state]')?.dataset.state === 'done'", 120)
    console.until("() => document.querySelectorAll('svg.chart rect').length >= 6")  # a bar per view
    report = console.page.locator("section.card:has(h3)").inner_text()
    assert "lens model" in report and "corners: median" in report and "the board as a ruler" in report
    drawn = "() => [...document.querySelectorAll('img.preview')].filter(i => i.complete && i.naturalWidth > 0)"
    console.until(f"{drawn}.length >= 2")  # where the corners fell, and their errors: until both are drawn
    assert console.errors == []


def test_a_folder_of_captures_is_uploaded_and_calibrated_from_the_page(
    console: Console, tmp_path_factory: pytest.TempPathFactory
) -> None:
    from rig.cli import main

    tmp = tmp_path_factory.mktemp("captures")
    views = tmp / "bench views"  # the folder's own name is not sent: any name will do
    config = _config(tmp, small_config_data())
    out = ["--out", str(tmp / "first"), "--save-views", str(views)]
    assert main(["calibrate", "camera", "--config", str(config), "--views", "4", *out]) == 0
    console.go("calibration")
    console.page.set_input_files("input[name=captures]", str(views))
    console.page.fill("input[name=model]", "k1")
    console.page.select_option("form[aria-label='calibrate from captures'] select[name=what]", "camera")
    console.page.click("text=Upload and calibrate")
    console.until("() => document.querySelector('section[data-state]')?.dataset.state === 'done'", 120)
    report = console.page.locator("section.card:has(h3)").inner_text()
    assert "camera0 (camera)" in report and "lens model k1" in report and "4 views used" in report
    status = console.page.locator("form[aria-label='calibrate from captures'] [role=status]").inner_text()
    assert "4 files in imports folder captures-" in status  # view_NN/camera0.png, one per pose
    assert console.errors == []


def test_the_rings_page_draws_an_adaptive_scans_plan(console: Console, daemon: Daemon) -> None:
    from tests.test_daemon import AUTH

    # the small rig's 320 x 256 camera holds 0.6 mm on every region, not the default 0.2
    job = daemon_http.post(f"{daemon.url}/v1/scans", json={"adaptive": True, "tolerance_mm": 0.6}, headers=AUTH).json()
    deadline = time.monotonic() + 180
    while daemon_http.get(f"{daemon.url}/v1/scans/{job['id']}").json()["state"] in ("queued", "running"):
        assert time.monotonic() < deadline
        time.sleep(0.2)
    manifest = daemon_http.get(f"{daemon.url}/v1/scans/{job['id']}/files/manifest.json").json()
    rings = len(manifest["adaptive"]["plan"]["radii_px"])
    console.go(f"rings/{job['id']}")
    console.until(f"() => document.querySelectorAll('svg.plan circle').length >= {rings}")  # drawn whole
    assert console.page.locator("svg.plan circle").count() == rings
    assert console.page.locator("svg.chart circle.ring").count() == rings - 1  # a spacing per pair of rings
    assert console.page.locator("svg.plan image").count() == 1  # over the pilot, as the projector saw it
    assert console.page.locator("svg.curve polyline").count() == 2  # predicted error against ring count
    assert "chosen" in console.page.locator("table:has(caption)").inner_text()
    assert console.errors == []
