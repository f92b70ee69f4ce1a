"""The console in Firefox (Debian's firefox-esr, driven over WebDriver BiDi by tests/firefox.py),
against a running daemon on the small simulated bench: log in, every page, a scan drawn in the
viewer, aim, live and a calibration's report, with no console error."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest

from tests.conftest import small_config_data
from tests.firefox import FIREFOX, Firefox, Tab
from tests.loopback import daemon_http
from tests.test_console_browser import FROM_THE_TOP, PAGES, REACHABLE
from tests.test_daemon import KEY, Daemon, _config

pytest.importorskip("websockets", reason="websockets is not installed (pip install -e '.[test]')")
pytestmark = pytest.mark.skipif(
    FIREFOX is None, reason="no Firefox here: `apt-get install firefox-esr` (.ci/run installs it)"
)


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    tmp = tmp_path_factory.mktemp("console-firefox")
    d = Daemon(_config(tmp, small_config_data(), max_queue=4), tmp / "daemon.log")
    yield d
    d.stop()


@pytest.fixture(scope="module")
def firefox(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Firefox]:
    tmp = tmp_path_factory.mktemp("firefox")
    browser = Firefox(tmp / "profile", tmp / "firefox.log")
    yield browser
    browser.close()


@pytest.fixture
def tab(firefox: Firefox, daemon: Daemon) -> Iterator[Tab]:
    """A tab on the console, logged in."""
    t = firefox.tab()
    t.goto(daemon.url + "/")
    if t.until("document.querySelector('main h1')?.textContent") == "Log in":
        _log_in(t, KEY)
    t.until("document.querySelector('main h1')?.textContent === 'Rig'")
    yield t
    t.close()


def _log_in(tab: Tab, key: str) -> None:
    tab.fill("input[name=key]", key)
    tab.press("Enter")


def _go(tab: Tab, daemon: Daemon, page: str) -> None:
    tab.goto(f"{daemon.url}/#/{page}")
    tab.until(f"location.hash === '#/{page}' && !!document.querySelector('main h1')")


def test_a_wrong_key_is_refused_and_the_right_one_logs_in_and_out(firefox: Firefox, daemon: Daemon) -> None:
    tab = firefox.tab()
    tab.goto(daemon.url + "/")
    tab.until("document.querySelector('main h1')?.textContent === 'Log in'")
    _log_in(tab, "this is not the key, sorry")
    tab.until("document.querySelector('form.login .error')?.textContent.includes('not valid')")
    assert all("403" in e for e in tab.errors)  # the refused login is the one failed request
    tab.errors.clear()
    _log_in(tab, KEY)
    tab.until("document.querySelector('main h1')?.textContent === 'Rig'")
    assert tab.evaluate("document.cookie") == ""  # HttpOnly: the page's scripts cannot read it
    tab.click("#logout")
    tab.until("document.querySelector('main h1')?.textContent === 'Log in'")
    tab.goto(daemon.url + "/")
    tab.until("document.querySelector('main h1')?.textContent === 'Log in'")  # the session is gone
    assert tab.errors == []
    tab.close()


def test_every_page_loads_without_a_console_error(tab: Tab, daemon: Daemon) -> None:
    for name in (*PAGES, "viewer"):
        _go(tab, daemon, name)
        tab.until("document.querySelector('main').children.length > 1")
    tab.goto(daemon.url + "/docs")
    tab.until("document.querySelectorAll('.swagger-ui .opblock').length > 10", 30)  # Swagger UI from local files
    assert tab.errors == []


def test_a_scan_from_the_scan_page_is_drawn_by_the_viewer(tab: Tab, daemon: Daemon) -> None:
    _go(tab, daemon, "scan")
    tab.select("select[name=codec]", "gray")
    tab.fill("input[name=label]", "from firefox")
    tab.click("text=Start scan")
    tab.until("document.querySelector('section[data-state]')?.dataset.state === 'done'", 180)
    assert "rms against the truth" in tab.evaluate("document.querySelector('.result').textContent")
    tab.click("text=Open in the 3D viewer")
    points = int(tab.until("document.querySelector('canvas.viewer')?.dataset.points", 60))
    assert points > 10_000
    image = tab.screenshot("canvas.viewer")
    background = np.array([28, 23, 18])  # BGR of the viewer's clear colour (0.07, 0.09, 0.11)
    drawn = np.abs(image.astype(int) - background).sum(axis=2) > 24
    assert drawn.mean() > 0.05  # WebGL2 drew the cloud over part of the canvas
    tab.select("select[name=mode]", "depth")
    changed = 0.0
    for _ in range(50):  # the next animation frame draws it
        changed = float(np.abs(tab.screenshot("canvas.viewer").astype(int) - image.astype(int)).mean())
        if changed > 2:
            break
    assert changed > 2  # another colouring, drawn
    assert tab.errors == []


def test_aim_frames_change_and_an_exposure_reaches_the_camera(tab: Tab, daemon: Daemon) -> None:
    frame = "Number(document.querySelector('canvas.frame')?.dataset.frame)"
    _go(tab, daemon, "aim")
    tab.click("text=Show pattern")
    first = int(tab.until(f"{frame} > 0 && {frame}", 30))
    tab.until(f"{frame} > {first} + 5", 30)
    tab.fill("input[name=exposure_us]", "4200")
    tab.press("Enter")
    tab.until("document.querySelector('canvas.frame').dataset.exposure === '4200'")
    assert daemon_http.get(f"{daemon.url}/v1/cameras").json()[0]["exposure_us"] == 4200
    tab.click("text=Dark")
    tab.until("document.querySelector('.state').textContent === 'off'")
    assert tab.errors == []


def test_the_live_page_updates(tab: Tab, daemon: Daemon) -> None:
    sequence = "Number(document.querySelector('img.depth')?.dataset.sequence)"
    _go(tab, daemon, "live")
    tab.click("text=Start")
    first = int(tab.until(f"{sequence} > 0 && {sequence}", 60))
    tab.until(f"{sequence} > {first}", 60)
    tab.click("text=Stop")
    tab.until("document.querySelector('.state').textContent === 'off'")
    assert tab.errors == []


def test_a_calibration_from_its_page_shows_its_report(tab: Tab, daemon: Daemon) -> None:
    """(Picking a folder of captures is tested in Chromium only: Firefox's BiDi input.setFiles
    refuses a directory, NS_ERROR_FILE_IS_DIRECTORY.)"""
    _go(tab, daemon, "calibration")
    tab.fill("input[name=views]", "5")
    tab.click("text=Calibrate")
    tab.until("document.querySelector('section[data-state]')?.dataset.state === 'done'", 120)
    tab.until("document.querySelectorAll('svg.chart rect').length >= 5")  # a bar per view
    report = tab.evaluate("document.querySelector('section.card:has(h3)').textContent")
    assert "lens model" in report and "corners: median" in report and "the board as a ruler" in report
    drawn = "[...document.querySelectorAll('img.preview')].filter(i => i.complete && i.naturalWidth > 0).length"
    tab.until(f"{drawn} >= 2")  # until both are drawn (until returns the first true value, 1 included)
    assert tab.errors == []


def test_every_control_of_every_page_is_reached_by_tab(tab: Tab, daemon: Daemon) -> None:
    for name in PAGES:
        _go(tab, daemon, name)
        tab.until("document.querySelector('main').children.length > 1")
        controls, before = tab.evaluate(f"({REACHABLE})()"), None
        for _ in range(30):  # until the page's first answers are drawn: its controls stay as they are
            if controls == before:
                break
            time.sleep(0.3)
            before, controls = controls, tab.evaluate(f"({REACHABLE})()")
        tab.evaluate(FROM_THE_TOP)
        reached = set()
        for _ in range(len(controls) + 5):
            tab.press("Tab")
            reached.add(tab.evaluate("document.activeElement.outerHTML.slice(0, 80)"))
        missing = [c for c in controls if c not in reached]
        assert not missing, f"{name}: not reached by Tab: {missing}"
    assert tab.errors == []
