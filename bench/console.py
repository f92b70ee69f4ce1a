"""What the operator's console costs and delivers, measured on a real daemon (the default simulated
bench, config/sim.yaml) and Debian's headless chromium driven by Playwright:

- time to first paint of `/` (logged in) and of the 3D viewer with a scan of about a million points
  (navigation start to the cloud drawn), at the default point budget and at full resolution;
- bytes sent for that scan: cloud.bin at the default budget and at full resolution, against cloud.ply;
- camera-view frames per second delivered to one and to four clients while scans run, and the scans'
  time with and without four viewers open.

    python bench/console.py [--rounds 9] [--docs]

--docs writes the table into docs/console.md. Prints JSON.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import httpx

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _browser import chromium_path, log_in, until  # noqa: E402
from _daemon import daemon_config  # noqa: E402
from _readme import replace_block  # noqa: E402

from rig.api.clouds import DEFAULT_BUDGET  # noqa: E402
from tests.conftest import default_config_data  # noqa: E402
from tests.test_daemon import AUTH, Daemon  # noqa: E402

TIMEOUT_S = 300.0


def _scan(daemon: Daemon) -> dict[str, Any]:
    """A phase scan, waited for; its record (the job's own start and end times)."""
    job = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH, timeout=30).json()
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        record = httpx.get(f"{daemon.url}/v1/scans/{job['id']}", timeout=30).json()
        if record["state"] not in ("queued", "running"):
            if record["state"] != "done":
                raise RuntimeError(f"scan {job['id']}: {record['state']} {record['error']}")
            return record
        time.sleep(0.05)
    raise RuntimeError("a scan did not finish")


def _seconds(record: dict[str, Any]) -> float:
    from datetime import datetime

    return (datetime.fromisoformat(record["finished"]) - datetime.fromisoformat(record["started"])).total_seconds()


class Viewers:
    """`count` clients each showing camera 0 as the console does (640 wide, clipped pixels marked),
    asking for the next frame once they have the last; `received` counts each one's frames."""

    def __init__(self, daemon: Daemon, count: int) -> None:
        self.url, self.received, self.stop = daemon.url, [0] * count, threading.Event()
        self.threads = [threading.Thread(target=self._watch, args=(k,), daemon=True) for k in range(count)]
        for t in self.threads:
            t.start()

    def _watch(self, k: int) -> None:
        last = 0
        with httpx.Client(timeout=30) as client:
            while not self.stop.is_set():
                query = {"after": last, "width": 640, "overlay": True}
                r = client.get(f"{self.url}/v1/cameras/0/frame.jpg", params=query)
                if r.status_code == 200:
                    last, self.received[k] = int(r.headers["x-frame"]), self.received[k] + 1

    def close(self) -> None:
        self.stop.set()
        for t in self.threads:
            t.join(35)


def interleaved(daemon: Daemon, rounds: int) -> list[dict[str, Any]]:
    """Scans alone, with one viewer and with four, in turn, `rounds` times (so that the machine's
    drift falls on each alike); each viewer count's median scan time and frames delivered per
    second to each viewer while its scans ran."""
    counts = (0, 1, 4)
    times: dict[int, list[float]] = {n: [] for n in counts}
    rates: dict[int, list[float]] = {n: [] for n in counts}
    for _ in range(rounds):
        for n in counts:
            watching = Viewers(daemon, n)
            started = time.monotonic()
            times[n].append(_seconds(_scan(daemon)))
            elapsed = time.monotonic() - started
            watching.close()
            rates[n] += [k / elapsed for k in watching.received]
    return [
        {
            "viewers": n,
            "scan_s_median": round(statistics.median(times[n]), 3),
            "scan_s": times[n],
            **({"frames_per_s_per_viewer_median": round(statistics.median(rates[n]), 2)} if n else {}),
        }
        for n in counts
    ]


def aim_rates(daemon: Daemon, seconds: float = 5.0) -> dict[str, float]:
    """Frames per second each viewer gets in aim mode (no job running), with one and with four."""
    httpx.post(f"{daemon.url}/v1/aim", json={"pattern": "crosshair", "seconds": 120}, headers=AUTH, timeout=30)
    out = {}
    for n in (1, 4):
        watching = Viewers(daemon, n)
        time.sleep(1.0)  # the rig open and frames flowing
        before = list(watching.received)
        time.sleep(seconds)
        watching.close()
        got = [(a - b) / seconds for a, b in zip(watching.received, before, strict=True)]
        out[f"viewers_{n}"] = round(statistics.median(got), 2)
    httpx.delete(f"{daemon.url}/v1/aim", headers=AUTH, timeout=30)
    return out


def browser_figures(daemon: Daemon, scan_id: str) -> dict[str, Any]:
    from playwright.sync_api import sync_playwright

    chromium = chromium_path()
    out: dict[str, Any] = {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        context = browser.new_context(viewport={"width": 1280, "height": 900})
        log_in(context.new_page(), daemon.url)
        page = context.new_page()
        page.goto(daemon.url + "/#/rig")
        page.wait_for_selector("h1:has-text('Rig')")
        paint = "() => performance.getEntriesByName('first-contentful-paint')[0]?.startTime"
        out["first_paint_ms"] = round(until(page, paint), 1)
        viewer = context.new_page()
        viewer.goto(f"{daemon.url}/#/viewer/{scan_id}")
        drawn = "() => document.querySelector('canvas.viewer')?.dataset.drawnAt"
        out["viewer_drawn_ms"] = round(float(until(viewer, drawn)), 1)
        out["viewer_points"] = int(viewer.evaluate("() => document.querySelector('canvas.viewer').dataset.points"))
        before = float(until(viewer, drawn))
        clicked = viewer.evaluate("() => performance.now()")
        viewer.click("text=Full resolution")
        redrawn = f"() => Number(document.querySelector('canvas.viewer').dataset.drawnAt) > {before} && {drawn[6:]}"
        out["full_resolution_ms"] = round(float(until(viewer, redrawn)) - clicked, 1)
        out["full_resolution_points"] = int(
            viewer.evaluate("() => document.querySelector('canvas.viewer').dataset.points")
        )
        browser.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=9, help="scans per viewer count (median), interleaved")
    parser.add_argument("--docs", "--readme", dest="readme", action="store_true", help="write docs/console.md's table")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        daemon = Daemon(daemon_config(folder, folder / "data", default_config_data()), folder / "daemon.log")
        try:
            first = _scan(daemon)  # warms the rig (ray casts, numba) and is the scan the viewer shows
            sizes = {
                "cloud_ply": len(httpx.get(f"{daemon.url}/v1/scans/{first['id']}/files/cloud.ply", timeout=60).content),
                "default_budget": len(httpx.get(f"{daemon.url}/v1/scans/{first['id']}/cloud.bin", timeout=60).content),
                "full_resolution": len(
                    httpx.get(
                        f"{daemon.url}/v1/scans/{first['id']}/cloud.bin", params={"budget": 0}, timeout=60
                    ).content
                ),
            }
            browser = browser_figures(daemon, first["id"])
            runs = interleaved(daemon, args.rounds)
            aiming = aim_rates(daemon)
        finally:
            daemon.stop()
    alone = runs[0]["scan_s"]
    result = {
        "machine": {"platform": platform.platform(), "cores": __import__("os").cpu_count()},
        "scan_points": first["result"]["points"],
        "default_budget_points": DEFAULT_BUDGET,
        "bytes": sizes,
        "browser": browser,
        "scans": runs,
        "aim_frames_per_s_per_viewer": aiming,
        # each round's scan with viewers against the same round's scan alone: the machine's drift
        # between rounds (it is shared) falls out
        "scan_time_with_one_viewer": round(
            statistics.median(a / b for a, b in zip(runs[1]["scan_s"], alone, strict=True)), 3
        ),
        "scan_time_with_four_viewers": round(
            statistics.median(a / b for a, b in zip(runs[2]["scan_s"], alone, strict=True)), 3
        ),
    }
    print(json.dumps(result, indent=2))
    if args.readme:
        replace_block("console-figures", _table(result))


def _table(r: dict[str, Any]) -> str:
    b, s, runs, aim = r["browser"], r["bytes"], r["scans"], r["aim_frames_per_s_per_viewer"]
    one, four = runs[1]["frames_per_s_per_viewer_median"], runs[2]["frames_per_s_per_viewer_median"]
    rows = [
        ("first paint of `/` (logged in)", f"{b['first_paint_ms']:.0f} ms"),
        (f"viewer drawn, {b['viewer_points']:,} of {r['scan_points']:,} points", f"{b['viewer_drawn_ms']:.0f} ms"),
        (f"full resolution drawn ({b['full_resolution_points']:,} points)", f"{b['full_resolution_ms']:.0f} ms"),
        ("bytes: cloud.bin at the default budget", f"{s['default_budget'] / 1e6:.1f} MB"),
        (
            "bytes: cloud.bin at full resolution",
            f"{s['full_resolution'] / 1e6:.1f} MB (cloud.ply: {s['cloud_ply'] / 1e6:.1f} MB)",
        ),
        (
            "camera view in aim mode: one client / each of four",
            f"{aim['viewers_1']:.1f} / {aim['viewers_4']:.1f} frames/s",
        ),
        ("camera view, one client, while a scan runs", f"{one:.1f} frames/s"),
        ("camera view, four clients, while a scan runs", f"{four:.1f} frames/s each"),
        (
            "scan time with one / four viewers, against alone in the same round (median ratio)",
            f"{r['scan_time_with_one_viewer']:.2f}x / {r['scan_time_with_four_viewers']:.2f}x "
            f"(medians: alone {runs[0]['scan_s_median']:.2f} s, four viewers {runs[2]['scan_s_median']:.2f} s)",
        ),
    ]
    lines = ["| measured | figure |", "|---|---|", *[f"| {a} | {b} |" for a, b in rows]]
    return "\n".join(lines) + f"\n\nMeasured by `python bench/console.py --docs` on {r['machine']['cores']} cores."


if __name__ == "__main__":
    main()
