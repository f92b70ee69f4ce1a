"""Driving the console in Debian's chromium for the console's benchmark and screenshots."""

from __future__ import annotations

import shutil
import time
from typing import Any

from tests.test_daemon import KEY


def chromium_path() -> str:
    found = shutil.which("chromium")
    if found is None:
        raise SystemExit("no chromium: apt-get install chromium")
    return found


def log_in(page: Any, url: str) -> None:
    page.goto(url + "/")
    page.fill("input[name=key]", KEY)
    page.press("input[name=key]", "Enter")
    page.wait_for_selector("h1:has-text('Rig')")


def until(page: Any, script: str, timeout_s: float = 300.0) -> Any:
    """Poll `script` (a function) in the page until it returns something true (Playwright's
    wait_for_function evaluates a string in the page, which the console's CSP forbids)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = page.evaluate(script)
        if value:
            return value
        time.sleep(0.02)
    raise RuntimeError(f"not within {timeout_s} s: {script}")
