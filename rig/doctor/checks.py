"""`slrig doctor`: check a rig config against this machine (device nodes, access, libraries), and
measure each projector's display-to-capture latency."""

from __future__ import annotations

import glob
import importlib.util
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from rig.config import RigConfig
from rig.doctor.inventory import usb_devices
from rig.rig import Rig
from rig.store.atomic import write_atomic

LATENCY_FILE = "latency.json"
UDEV_RULES = Path("/etc/udev/rules.d/60-slrig.rules")


def _access(path: str, group: str) -> str | None:
    if not os.path.exists(path):
        return f"{path} does not exist: is it plugged in? (`slrig devices` lists what is attached)"
    if not os.access(path, os.R_OK | os.W_OK):
        return f"no access to {path}: add the service user to the '{group}' group (and log in again)"
    return None


def _lightcrafter_usb() -> str | None:
    listing = usb_devices()
    if "error" in listing:
        return str(listing["error"])
    found = [d for d in listing["devices"] if d["id"] == "0451:6401"]
    if not found:
        return "no LightCrafter 4500 (USB 0451:6401) attached: is it powered and its USB cable in?"
    bus, address = found[0]["bus"], found[0]["address"]
    node = f"/dev/bus/usb/{bus:03d}/{address:03d}" if bus is not None and address is not None else ""
    if node and os.path.exists(node) and not os.access(node, os.R_OK | os.W_OK):
        return f"no access to {node}: install systemd/60-slrig.rules and add the service user to 'plugdev'"
    return None


def check(config: RigConfig) -> list[dict[str, str]]:
    """Problems, each with the device it concerns and how to fix it; empty when all is well."""
    problems: list[dict[str, str]] = []

    def problem(device: str, text: str) -> None:
        problems.append({"device": device, "problem": text})

    for p in config.projectors:
        if p.driver == "lightcrafter":
            issue = _lightcrafter_usb()
            if issue:
                problem(p.name, issue)
        if p.driver in ("hdmi", "lightcrafter") and p.hdmi.video_driver == "kmsdrm":
            cards = glob.glob("/dev/dri/card*")
            if not cards:
                problem(p.name, "no /dev/dri/card*: no display output (kmsdrm needs a GPU with a connected output)")
            elif not any(os.access(c, os.R_OK | os.W_OK) for c in cards):
                problem(p.name, "no access to /dev/dri: add the service user to the 'video' group")
            if importlib.util.find_spec("pygame") is None:
                problem(p.name, "pygame-ce is not installed: pip install 'slrig[hdmi]'")
        if p.power is not None and p.power.url and p.power.url.startswith("/dev/"):
            issue = _access(p.power.url, "dialout")
            if issue:
                problem(f"{p.name}-power", issue)
    for c in config.cameras:
        if c.driver == "v4l2" and c.v4l2 is not None:
            issue = _access(c.v4l2.device, "video")
            if issue:
                problem(c.name, issue)
        if c.driver == "oak" and c.oak.backend == "depthai":
            if importlib.util.find_spec("depthai") is None:
                problem(c.name, "depthai is not installed: pip install depthai")
            if not UDEV_RULES.exists():
                problem(c.name, f"{UDEV_RULES} is missing: install systemd/60-slrig.rules (OAKs need plugdev access)")
    real = not config.simulated
    if real and config.calibration.file is None:
        problems.append(
            {
                "device": "rig",
                "problem": "no calibration.file: the geometry is nominal; run "
                "`slrig calibrate rig` and point calibration.file at the result",
            }
        )
    return problems


def measure_latency(rig: Rig, projector: int, camera: int = 0, max_frames: int = 120) -> float:
    """Seconds from show() of a white frame (after black) to the light on the scene, erring long:
    frames are taken as they come until their brightness stops rising, and the first one lit to
    within 3 % of that plateau was exposed entirely after the light arrived; its exposure start,
    less the time of show(), is the latency (at most one frame period too long, never too short)."""
    device, cam = rig.projectors[projector], rig.cameras[camera]
    width, height = device.resolution
    rig.all_dark()
    rig.wait(0.5)
    cam.flush()
    dark = float(cam.capture().image.mean())
    device.show(np.full((height, width), 255, np.uint8))
    shown = rig.clock.now()
    seen: list[tuple[float, float]] = []  # (exposure start, brightness)
    try:
        for _ in range(max_frames):
            frame = cam.capture()
            seen.append((frame.timestamp_s - frame.exposure_us * 1e-6, float(frame.image.mean())))
            if len(seen) >= 3 and seen[-1][1] > dark + 10 and abs(seen[-1][1] - seen[-2][1]) <= 0.01 * seen[-1][1]:
                plateau = seen[-1][1]
                first = next(start for start, level in seen if level >= dark + 0.97 * (plateau - dark))
                return max(0.0, first - shown)
        raise TimeoutError(f"no steady light from {rig.config.projectors[projector].name} within {max_frames} frames")
    finally:
        rig.all_dark()


def store_latencies(folder: Path, values: dict[str, float]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LATENCY_FILE
    existing: dict[str, Any] = json.loads(path.read_text()) if path.is_file() else {}
    existing.update({name: round(v, 4) for name, v in values.items()})
    write_atomic(path, json.dumps(existing, indent=2).encode())
    return path
