"""Screenshots of the console's main pages for the manual (docs/images/console_*.png), taken from a
running daemon on the default simulated bench in Debian's headless chromium: the rig, aiming with
the crosshair, a finished scan, its cloud in the 3D viewer, the scans list, live mode, a
calibration report and an adaptive scan's ring plan.

    python bench/console_screenshots.py

Prints JSON: the images written, and the scan and calibration they show.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _browser import chromium_path, log_in, until  # noqa: E402
from _daemon import daemon_config  # noqa: E402

from tests.conftest import default_config_data  # noqa: E402
from tests.test_daemon import Daemon  # noqa: E402

IMAGES = REPO / "docs" / "images"
VIEWPORT = {"width": 1280, "height": 860}


def _shoot(page: Any, name: str, written: list[str]) -> None:
    path = IMAGES / f"console_{name}.png"
    page.screenshot(path=str(path))
    written.append(str(path.relative_to(REPO)))


DONE = "() => document.querySelector('section[data-state]')?.dataset.state === 'done'"
JOB_ID = "() => document.querySelector('section[data-state] h2').textContent.split(' ')[1]"


def take(daemon: Daemon) -> dict[str, Any]:
    from playwright.sync_api import sync_playwright

    chromium = chromium_path()
    written: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport=VIEWPORT)
        log_in(page, daemon.url)
        scan_id = _aim_scan_and_view(page, daemon.url, written)
        page.goto(daemon.url + "/#/live")
        page.click("text=Start")
        until(page, "() => Number(document.querySelector('img.depth')?.dataset.sequence) > 2")
        _shoot(page, "live", written)
        page.click("text=Stop")
        for name in ("scans", "rig"):
            page.goto(f"{daemon.url}/#/{name}")
            time.sleep(1.0)
            _shoot(page, name, written)
        _calibration_and_rings(page, daemon.url, written)
        browser.close()
    return {"images": written, "scan": scan_id}


def _aim_scan_and_view(page: Any, url: str, written: list[str]) -> str:
    page.goto(url + "/#/aim")
    page.select_option("select[name=pattern]", "crosshair")
    page.click("text=Show pattern")
    until(page, "() => Number(document.querySelector('canvas.frame')?.dataset.frame) > 10")
    page.evaluate("() => document.querySelector('.camera').scrollIntoView()")
    _shoot(page, "aim", written)
    page.click("text=Dark")
    page.goto(url + "/#/scan")
    page.fill("input[name=label]", "sphere on the plane")
    page.click("text=Start scan")
    until(page, DONE)
    page.evaluate("() => document.querySelector('section[data-state]').scrollIntoView()")
    _shoot(page, "scan", written)
    scan_id = str(page.evaluate(JOB_ID))
    page.goto(f"{url}/#/viewer/{scan_id}")
    until(page, "() => document.querySelector('canvas.viewer')?.dataset.drawn")
    page.select_option("select[name=mode]", "depth")
    box = page.locator("canvas.viewer").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] / 2 + 50, box["y"] + box["height"] / 2 + 25, steps=8)
    page.mouse.up()
    time.sleep(0.3)
    _shoot(page, "viewer", written)
    return scan_id


def _calibration_and_rings(page: Any, url: str, written: list[str]) -> None:
    page.goto(url + "/#/calibration")
    page.fill("input[name=views]", "10")
    page.click("text=Calibrate")
    until(page, "() => document.querySelectorAll('img.preview').length >= 2")
    time.sleep(0.5)
    page.evaluate("() => document.querySelector('.device').scrollIntoView()")
    _shoot(page, "calibration", written)
    page.goto(url + "/#/scan")
    page.check("input[name=adaptive]")
    page.click("text=Start scan")
    until(page, DONE)
    adaptive = page.evaluate(JOB_ID)
    page.goto(f"{url}/#/rings/{adaptive}")
    until(page, "() => document.querySelectorAll('svg.plan circle').length")
    time.sleep(0.5)
    page.evaluate("() => document.querySelector('.plan-card').scrollIntoView()")
    _shoot(page, "rings", written)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        daemon = Daemon(daemon_config(folder, folder / "data", default_config_data()), folder / "daemon.log")
        try:
            print(json.dumps(take(daemon), indent=2))
        finally:
            daemon.stop()


if __name__ == "__main__":
    main()
