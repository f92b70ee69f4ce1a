"""`slrig doctor`: a rig config checked against this machine (device nodes, access, libraries), by
what each driver of the table needs."""

from __future__ import annotations

import glob
import importlib.util
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rig.config import CameraConfig, DeviceKind, ProjectorConfig, RigConfig
from rig.doctor.inventory import usb_devices

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


def _display(p: ProjectorConfig) -> list[str]:
    if p.hdmi.video_driver != "kmsdrm":
        return []
    found = []
    cards = glob.glob("/dev/dri/card*")
    if not cards:
        found.append("no /dev/dri/card*: no display output (kmsdrm needs a GPU with a connected output)")
    elif not any(os.access(c, os.R_OK | os.W_OK) for c in cards):
        found.append("no access to /dev/dri: add the service user to the 'video' group")
    if importlib.util.find_spec("pygame") is None:
        found.append("pygame-ce is not installed: pip install 'slrig[hdmi]'")
    return found


def _lightcrafter(p: ProjectorConfig) -> list[str]:
    return [issue for issue in (_lightcrafter_usb(),) if issue] + _display(p)


def _serial_port(p: ProjectorConfig) -> list[str]:
    url = p.power.url if p.power is not None else None
    issue = _access(url, "dialout") if url and url.startswith("/dev/") else None
    return [issue] if issue else []


def _v4l2(c: CameraConfig) -> list[str]:
    issue = _access(c.v4l2.device, "video") if c.v4l2 is not None else None
    return [issue] if issue else []


def _oak(c: CameraConfig) -> list[str]:
    if c.oak.backend != "depthai":
        return []
    found = []
    if importlib.util.find_spec("depthai") is None:
        found.append("depthai is not installed: pip install depthai")
    if not UDEV_RULES.exists():
        found.append(f"{UDEV_RULES} is missing: install systemd/60-slrig.rules (OAKs need plugdev access)")
    return found


def _replay(c: CameraConfig) -> list[str]:
    """The recorded frames' folder is there, and holds images."""
    source = c.replay.source if c.replay is not None else None
    if source is None:
        return []
    folder = Path(source)
    if not folder.is_dir():
        return [f"replay.source {folder}: no such folder"]
    if not any(folder.glob(c.replay.files)):
        return [f"replay.source {folder}: no file matches {c.replay.files!r}"]
    return []


def _nothing(device: Any) -> list[str]:
    return []


# What each driver of the table (rig.config.drivers) needs from this machine.
NEEDS: dict[tuple[DeviceKind, str], Callable[[Any], list[str]]] = {
    (DeviceKind.PROJECTOR, "sim"): _nothing,
    (DeviceKind.PROJECTOR, "hdmi"): _display,
    (DeviceKind.PROJECTOR, "lightcrafter"): _lightcrafter,
    (DeviceKind.CAMERA, "sim"): _nothing,
    (DeviceKind.CAMERA, "v4l2"): _v4l2,
    (DeviceKind.CAMERA, "oak"): _oak,
    (DeviceKind.CAMERA, "replay"): _replay,
    (DeviceKind.POWER, "pjlink"): _nothing,  # a network address: nothing to check on this machine
    (DeviceKind.POWER, "benq"): _serial_port,
    (DeviceKind.POWER, "epson"): _serial_port,
    (DeviceKind.POWER, "optoma"): _serial_port,
}


def check(config: RigConfig) -> list[dict[str, str]]:
    """Problems, each with the device it concerns and how to fix it; empty when all is well."""
    problems: list[dict[str, str]] = []
    for p in config.projectors:
        problems += [{"device": p.name, "problem": text} for text in NEEDS[(DeviceKind.PROJECTOR, p.driver)](p)]
        if p.power is not None:
            found = NEEDS[(DeviceKind.POWER, p.power.protocol)](p)
            problems += [{"device": f"{p.name}-power", "problem": text} for text in found]
    for c in config.cameras:
        problems += [{"device": c.name, "problem": text} for text in NEEDS[(DeviceKind.CAMERA, c.driver)](c)]
    if not config.simulated and config.calibration.file is None:
        problems.append(
            {
                "device": "rig",
                "problem": "no calibration.file: the geometry is nominal; run "
                "`slrig calibrate rig` and point calibration.file at the result",
            }
        )
    return problems
