"""A small WebDriver BiDi client for Debian's Firefox, which speaks the W3C protocol itself (no
geckodriver): enough to log in, click, type, pick files, evaluate, capture an element and collect
console errors, as tests/test_console_firefox.py needs. Playwright's Firefox is a patched build it
downloads; this drives the distribution's browser, as a lab's would be. Every wait has a timeout."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from tests.ports import free_port

FIREFOX = shutil.which("firefox-esr") or shutil.which("firefox")
# Headless Firefox has WebGL only through Mesa's software EGL (no display, no GPU): forced here.
ENVIRONMENT = {"MOZ_WEBGL_FORCE_EGL": "1", "EGL_PLATFORM": "surfaceless", "LIBGL_ALWAYS_SOFTWARE": "1"}
PREFERENCES = {
    "webgl.force-enabled": True,
    "browser.shell.checkDefaultBrowser": False,
    "datareporting.policy.dataSubmissionEnabled": False,
    "app.update.disabledForTesting": True,
    "network.captive-portal-service.enabled": False,
    "browser.safebrowsing.update.enabled": False,
    "extensions.update.enabled": False,
    "remote.prefs.recommended": True,
}
KEYS = {"Enter": "\ue007", "Tab": "\ue004"}


class BidiError(AssertionError):
    """Raised when Firefox answers a command with an error, or does not answer in time."""


class Firefox:
    """One headless Firefox with a fresh profile, and its BiDi session."""

    def __init__(self, profile: Path, log: Path, timeout_s: float = 30.0) -> None:
        from websockets.sync.client import connect

        assert FIREFOX is not None
        profile.mkdir(parents=True, exist_ok=True)
        lines = (f"user_pref({json.dumps(k)}, {json.dumps(v)});" for k, v in PREFERENCES.items())
        (profile / "user.js").write_text("\n".join(lines) + "\n")
        port = free_port()
        self.timeout_s = timeout_s
        with log.open("ab") as err:
            self.process = subprocess.Popen(
                [FIREFOX, "--headless", "--no-remote", "--profile", str(profile), "--remote-debugging-port", str(port)],
                env={**os.environ, **ENVIRONMENT},
                stdout=subprocess.DEVNULL,
                stderr=err,
                start_new_session=True,
            )
        self._open = contextlib.ExitStack()
        self._next = 0
        self.errors: dict[str, list[str]] = {}  # per browsing context
        try:
            deadline = time.monotonic() + 60
            while True:
                try:
                    url = f"ws://127.0.0.1:{port}/session"
                    self._socket = self._open.enter_context(connect(url, max_size=None, open_timeout=5))
                    break
                except OSError:
                    if time.monotonic() > deadline or self.process.poll() is not None:
                        raise BidiError(f"Firefox did not open its BiDi port: {log.read_text()[-2000:]}") from None
                    time.sleep(0.2)
            self.call("session.new", {"capabilities": {"alwaysMatch": {"acceptInsecureCerts": False}}})
            self.call("session.subscribe", {"events": ["log.entryAdded"]})
        except BaseException:
            self.close()
            raise

    def call(self, method: str, params: dict[str, Any]) -> dict[str, Any]:
        self._next += 1
        self._socket.send(json.dumps({"id": self._next, "method": method, "params": params}))
        deadline = time.monotonic() + self.timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BidiError(f"{method}: no answer within {self.timeout_s} s")
            message = json.loads(self._socket.recv(timeout=left))
            if message.get("type") == "event":
                self._event(message)
            elif message.get("id") == self._next:
                if message.get("type") == "error":
                    raise BidiError(f"{method}: {message.get('error')}: {message.get('message')}")
                return message["result"]

    def _event(self, message: dict[str, Any]) -> None:
        entry = message["params"]
        if message["method"] == "log.entryAdded" and entry.get("level") == "error":
            context = entry.get("source", {}).get("context", "")
            self.errors.setdefault(context, []).append(entry.get("text", ""))

    def tab(self, width: int = 1280, height: int = 900) -> Tab:
        context = self.call("browsingContext.create", {"type": "tab"})["context"]
        self.call("browsingContext.setViewport", {"context": context, "viewport": {"width": width, "height": height}})
        return Tab(self, context)

    def close(self) -> None:
        try:
            self._open.close()
        finally:
            if self.process.poll() is None:
                os.killpg(self.process.pid, signal.SIGTERM)
                try:
                    self.process.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(self.process.pid, signal.SIGKILL)
                    self.process.wait(10)


class Tab:
    """One browsing context: navigation, evaluation and real pointer and key input."""

    def __init__(self, browser: Firefox, context: str) -> None:
        self.browser = browser
        self.context = context

    @property
    def errors(self) -> list[str]:
        return self.browser.errors.setdefault(self.context, [])

    def goto(self, url: str) -> None:
        self.browser.call("browsingContext.navigate", {"context": self.context, "url": url, "wait": "complete"})

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression (awaited), through JSON."""
        result = self.browser.call(
            "script.evaluate",
            {
                "expression": f"(async () => JSON.stringify(await ({expression})))()",
                "target": {"context": self.context},
                "awaitPromise": True,
            },
        )
        if result["type"] == "exception":
            raise BidiError(f"{expression}: {result['exceptionDetails'].get('text')}")
        value = result["result"].get("value")
        return None if value is None else json.loads(value)

    def until(self, expression: str, timeout_s: float = 30.0) -> Any:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                value = self.evaluate(expression)
            except BidiError:  # a navigation replaced the page under the evaluation: ask again
                value = None
            if value:
                return value
            time.sleep(0.1)
        raise AssertionError(f"not within {timeout_s} s: {expression}")

    def element(self, selector: str, timeout_s: float = 10.0) -> dict[str, str]:
        """A shared reference to the first element `selector` matches, once there is one; `text=X`
        is the first button or link whose text is X."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            result = self.browser.call(
                "script.evaluate",
                {
                    "expression": _finder(selector),
                    "target": {"context": self.context},
                    "awaitPromise": False,
                },
            )
            node = result.get("result", {})
            if node.get("type") == "node":
                return {"sharedId": node["sharedId"]}
            time.sleep(0.1)
        raise AssertionError(f"no element {selector} within {timeout_s} s")

    def click(self, selector: str) -> None:
        target = self.element(selector)
        self._settle_in_view(selector)
        pointer = [
            {"type": "pointerMove", "x": 0, "y": 0, "origin": {"type": "element", "element": target}},
            {"type": "pointerDown", "button": 0},
            {"type": "pointerUp", "button": 0},
        ]
        self._actions([{"type": "pointer", "id": "mouse", "actions": pointer}])

    def _settle_in_view(self, selector: str, timeout_s: float = 5.0) -> None:
        """Scroll the element to the middle of the view until it stays there: the page may still be
        laying out (a picture that loads above it moves it down after the scroll)."""
        where = (
            f"(e => {{ e.scrollIntoView({{block: 'center'}}); const r = e.getBoundingClientRect(); "
            f"return [r.top, r.bottom <= innerHeight && r.top >= 0]; }})({_finder(selector)})"
        )
        deadline, last = time.monotonic() + timeout_s, None
        while time.monotonic() < deadline:
            now = self.evaluate(where)
            if now == last and now[1]:
                return
            last = now
            time.sleep(0.05)

    def fill(self, selector: str, text: str) -> None:
        """Focus the field, clear it, and type `text` key by key."""
        self.click(selector)
        self.evaluate(f"document.querySelector({json.dumps(selector)}).select()")
        self.type(text)

    def type(self, text: str) -> None:
        keys = [{"type": kind, "value": c} for c in text for kind in ("keyDown", "keyUp")]
        self._actions([{"type": "key", "id": "keyboard", "actions": keys}])

    def press(self, key: str) -> None:
        self.type(KEYS[key])

    def select(self, selector: str, value: str) -> None:
        """Choose an option as Playwright's select_option does: the value set, input and change sent."""
        self.evaluate(
            f"(s => {{ s.focus(); s.value = {json.dumps(value)}; for (const t of ['input', 'change']) "
            f"s.dispatchEvent(new Event(t, {{bubbles: true}})); }})(document.querySelector({json.dumps(selector)}))"
        )

    def set_files(self, selector: str, paths: list[Path]) -> None:
        self.browser.call(
            "input.setFiles",
            {"context": self.context, "element": self.element(selector), "files": [str(p) for p in paths]},
        )

    def screenshot(self, selector: str) -> np.ndarray:
        """What the element shows, as a BGR image."""
        clip = {"type": "element", "element": self.element(selector)}
        data = self.browser.call("browsingContext.captureScreenshot", {"context": self.context, "clip": clip})["data"]
        return cv2.imdecode(np.frombuffer(base64.b64decode(data), np.uint8), cv2.IMREAD_COLOR)

    def close(self) -> None:
        self.browser.call("browsingContext.close", {"context": self.context})

    def _actions(self, sources: list[dict[str, Any]]) -> None:
        self.browser.call("input.performActions", {"context": self.context, "actions": sources})
        self.browser.call("input.releaseActions", {"context": self.context})


def _finder(selector: str) -> str:
    """JavaScript for the element `selector` names (a CSS selector, or text=X)."""
    if selector.startswith("text="):
        text = json.dumps(selector.removeprefix("text="))
        return f"[...document.querySelectorAll('button, a')].find((e) => e.textContent.trim() === {text})"
    return f"document.querySelector({json.dumps(selector)})"
