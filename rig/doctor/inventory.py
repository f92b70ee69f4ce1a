"""What is attached to this machine: USB devices (known ones named), V4L2 video nodes, serial
ports, OAK cameras. `slrig devices` prints it; `slrig doctor` (later) checks a config against it."""

from __future__ import annotations

import glob
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from drivers.machine import attached_usb
from rig.config import DRIVERS

OTHER_USB = {(0x0451, 0xC900): "TI DLP LightCrafter 6500/9000 (DLPC900)"}  # known, no driver yet


def known_usb() -> dict[tuple[int, int], str]:
    """USB ids inventory names: every driver's in the table (DriverEntry.usb_ids), and a few more."""
    return {**OTHER_USB, **{ids: label for entry in DRIVERS for ids, label in entry.usb_ids.items()}}


def usb_devices(finder: Callable[..., Any] | None = None) -> dict[str, Any]:
    listing = attached_usb(finder)
    known = known_usb()
    devices = [
        {
            "id": f"{d['vid']:04x}:{d['pid']:04x}",
            "bus": d["bus"],
            "address": d["address"],
            "known": known.get((d["vid"], d["pid"])),
        }
        for d in listing["devices"]
    ]
    return {**listing, "devices": devices}


def video_nodes(sysfs: str = "/sys/class/video4linux") -> list[dict[str, Any]]:
    nodes = []
    for path in sorted(glob.glob("/dev/video*")):
        name_file = Path(sysfs) / os.path.basename(path) / "name"
        try:
            name = name_file.read_text().strip()
        except OSError:
            name = None
        nodes.append({"path": path, "name": name, "readable": os.access(path, os.R_OK | os.W_OK)})
    return nodes


def serial_ports() -> list[dict[str, Any]]:
    from serial.tools import list_ports

    return [
        {
            "path": p.device,
            "description": p.description,
            "hwid": p.hwid,
            "readable": os.access(p.device, os.R_OK | os.W_OK),
        }
        for p in list_ports.comports()
    ]


def oak_cameras() -> dict[str, Any]:
    try:
        import depthai  # type: ignore[import-not-found]
    except ImportError:
        return {"error": "depthai is not installed (pip install depthai)", "devices": []}
    try:
        found = depthai.Device.getAllAvailableDevices()
    except Exception as exc:
        return {"error": f"depthai could not search: {exc}", "devices": []}
    return {"devices": [{"id": d.getDeviceId(), "name": getattr(d, "name", None)} for d in found]}


def machine_inventory(usb_finder: Callable[..., Any] | None = None) -> dict[str, Any]:
    return {"usb": usb_devices(usb_finder), "video": video_nodes(), "serial": serial_ports(), "oak": oak_cameras()}


def describe(found: dict[str, Any]) -> list[str]:
    """The inventory as lines a person reads."""
    lines = ["USB:"]
    if found["usb"].get("error"):
        lines.append(f"  {found['usb']['error']}")
    for d in found["usb"]["devices"]:
        lines.append(f"  {d['id']}  bus {d['bus']} address {d['address']}" + (f"  {d['known']}" if d["known"] else ""))
    lines.append("Video (V4L2):" if found["video"] else "Video (V4L2): none")
    for v in found["video"]:
        access = "" if v["readable"] else "  (no access: add the service user to the 'video' group)"
        lines.append(f"  {v['path']}  {v['name'] or ''}{access}")
    lines.append("Serial:" if found["serial"] else "Serial: none")
    for s in found["serial"]:
        access = "" if s["readable"] else "  (no access: add the service user to the 'dialout' group)"
        lines.append(f"  {s['path']}  {s['description']}  {s['hwid']}{access}")
    lines.append("OAK:")
    if found["oak"].get("error"):
        lines.append(f"  {found['oak']['error']}")
    lines.extend(f"  {d['id']}  {d['name'] or ''}" for d in found["oak"]["devices"])
    return lines
