"""What a driver needs of this machine, checked where `slrig doctor` asks (each driver's
`machine_problems`, named by the driver table): device nodes and the groups that open them, Python
packages, udev rules, and the USB devices attached."""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

UDEV_RULES = Path("/etc/udev/rules.d/60-slrig.rules")


def access_problem(path: str, group: str) -> str | None:
    """Why `path` cannot be opened for reading and writing (and the group that would let it), or None."""
    if not os.path.exists(path):
        return f"{path} does not exist: is it plugged in? (`slrig devices` lists what is attached)"
    if not os.access(path, os.R_OK | os.W_OK):
        return f"no access to {path}: add the service user to the '{group}' group (and log in again)"
    return None


def package_problem(module: str, install: str, package: str | None = None) -> str | None:
    """How to install `module` (of the distribution `package`, where named otherwise) where it is
    not importable, or None."""
    found = importlib.util.find_spec(module) is not None
    return None if found else f"{package or module} is not installed: {install}"


def attached_usb(finder: Callable[..., Any] | None = None) -> dict[str, Any]:
    """The USB devices attached, each {"vid", "pid", "bus", "address"}, or {"error": why not} (no
    libusb, no pyusb)."""
    try:
        import usb.core

        found = list((finder or usb.core.find)(find_all=True))
    except Exception as exc:
        return {"error": f"cannot list USB devices ({exc}); install libusb-1.0-0", "devices": []}
    devices = [
        {
            "vid": int(d.idVendor),
            "pid": int(d.idProduct),
            "bus": getattr(d, "bus", None),
            "address": getattr(d, "address", None),
        }
        for d in found
    ]
    return {"devices": devices}
