"""`slrig doctor`: a rig config checked against this machine (device nodes, access, libraries), by
what each driver of the table needs (its entry's `needs`, a check in the driver's own module)."""

from __future__ import annotations

from rig.config import DeviceKind, RigConfig, driver, named


def _lacks(kind: DeviceKind, name: str, device: object) -> list[str]:
    """What this machine lacks for one device, by its driver's check (DriverEntry.needs)."""
    entry = driver(kind, name)
    return [] if entry.needs is None else list(named(entry.needs)(device))


def check(config: RigConfig) -> list[dict[str, str]]:
    """Problems, each with the device it concerns and how to fix it; empty when all is well."""
    problems: list[dict[str, str]] = []
    for p in config.projectors:
        problems += [{"device": p.name, "problem": text} for text in _lacks(DeviceKind.PROJECTOR, p.driver, p)]
        if p.power is not None:
            found = _lacks(DeviceKind.POWER, p.power.protocol, p)
            problems += [{"device": f"{p.name}-power", "problem": text} for text in found]
    for c in config.cameras:
        problems += [{"device": c.name, "problem": text} for text in _lacks(DeviceKind.CAMERA, c.driver, c)]
    if not config.simulated and config.calibration.file is None:
        problems.append(
            {
                "device": "rig",
                "problem": "no calibration.file: the geometry is nominal; run "
                "`slrig calibrate rig` and point calibration.file at the result",
            }
        )
    return problems
