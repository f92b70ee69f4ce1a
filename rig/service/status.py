"""What the service reports: each configured device, its driver and whether it is open; a finished
job's result files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivers.base import Device
from rig.config import DeviceKind, RigConfig
from rig.opened_rig import Rig
from rig.service.errors import JobConflictError, JobNotFoundError
from rig.service.jobs import Job, JobState


def device_views(config: RigConfig, rig: Rig | None) -> list[dict[str, Any]]:
    """Projectors, their power controls and cameras as configured; `open` tells whether the device
    is open now (devices stay open between jobs, and are closed after a failure)."""
    out: list[dict[str, Any]] = []

    def add(name: str, kind: DeviceKind, driver: str, resolution: list[int] | None, device: Device | None) -> None:
        open_now = device is not None and device.is_open
        out.append({"name": name, "kind": kind, "driver": driver, "resolution": resolution, "open": open_now})

    def live(devices: list[Any], i: int) -> Device | None:
        return devices[i] if rig is not None and i < len(devices) else None

    powers = {device.name: device for device in rig.extras} if rig is not None else {}
    for i, p in enumerate(config.projectors):
        add(p.name, DeviceKind.PROJECTOR, p.driver, list(p.resolution), live(rig.projectors if rig else [], i))
        if p.power is not None:
            name = f"{p.name}-power"
            add(name, DeviceKind.POWER, p.power.protocol, None, powers.get(name))
    for i, c in enumerate(config.cameras):
        add(c.name, DeviceKind.CAMERA, c.driver, list(c.resolution), live(rig.cameras if rig else [], i))
    return out


def result_file(job: Job, folder: Path, name: str) -> Path:
    """The file `name` of a finished job stored in `folder`, when its result lists it."""
    if job.state is not JobState.DONE:
        raise JobConflictError(f"{job.kind} {job.id} is {job.state}; files exist once it is done")
    files = (job.result or {}).get("files", [])
    if name not in files:
        raise JobNotFoundError(f"{job.kind} {job.id} has no file {name!r}; it has {', '.join(files)}")
    path = folder / name
    if not path.is_file():
        raise JobNotFoundError(f"{job.kind} {job.id}: {name} is missing from the store")
    return path
