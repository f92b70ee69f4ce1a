"""The table of drivers: every `driver:` (and power `protocol:`) a config may name.

Each entry maps a name to the config sections its driver reads (one options model each, from
drivers.options), its capabilities, and its factory. The config's driver lists and driver checks
derive from this table, and the assembly builds every device through it, simulated ones included.

Factories are named ("module:function"), not imported: reading the table, as every config
validation does, loads no driver code, and the simulator (trimesh, Embree) loads only when a
simulated rig is opened. The assembly resolves them (rig.assembly.build.factory_of).
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel

from drivers.options import (
    LIGHTCRAFTER_RESOLUTION,
    HdmiOptions,
    LightCrafterOptions,
    OakOptions,
    PowerOptions,
    ReplayOptions,
    SimCameraOptions,
    SimProjectorOptions,
    V4l2Options,
)


class DeviceKind(enum.StrEnum):
    """What a device is to the rig; shared by the config, the service and the API."""

    PROJECTOR = "projector"
    CAMERA = "camera"
    POWER = "power"


@dataclass(frozen=True)
class Capabilities:
    """What a driver's device can do beyond its interface's minimum."""

    trigger_input: bool = False  # a camera whose exposures a trigger pulse starts (hardware sync)
    sequence_playback: bool = False  # a projector that plays a preloaded sequence and pulses a trigger out
    power_control: bool = False  # a projector whose power and input a `power:` section may switch


@dataclass(frozen=True)
class DriverEntry:
    name: str
    kind: DeviceKind
    summary: str
    factory: str  # "module:function"; the function takes (device config, index, world) and returns a Device
    sections: Mapping[str, type[BaseModel]] = field(default_factory=dict)  # config section -> its options
    capabilities: Capabilities = Capabilities()
    simulated: bool = False
    check: Callable[[Any], None] | None = None  # further checks of a device config; raises ValueError


def _lightcrafter_fits(device: Any) -> None:
    if tuple(device.resolution) != LIGHTCRAFTER_RESOLUTION:
        raise ValueError(f"resolution: a LightCrafter 4500 is {list(LIGHTCRAFTER_RESOLUTION)}")
    if device.sync == "hardware":
        device.lightcrafter.check_timing(device.pattern_period_us)


_HARDWARE = "rig.assembly.hardware"
_SIMULATED = "rig.assembly.simulated"

DRIVERS: tuple[DriverEntry, ...] = (
    DriverEntry(
        "sim",
        DeviceKind.PROJECTOR,
        "a projector of the simulated bench (streams patterns, or plays a sequence with sync: hardware)",
        f"{_SIMULATED}:projector",
        {"sim": SimProjectorOptions},
        Capabilities(sequence_playback=True),
        simulated=True,
    ),
    DriverEntry(
        "hdmi",
        DeviceKind.PROJECTOR,
        "any projector as a display output, through a worker process (pygame-ce)",
        f"{_HARDWARE}:hdmi_projector",
        {"hdmi": HdmiOptions},
        Capabilities(power_control=True),
    ),
    DriverEntry(
        "lightcrafter",
        DeviceKind.PROJECTOR,
        "TI DLP LightCrafter 4500: USB control (DLPC350) and its HDMI video input",
        f"{_HARDWARE}:lightcrafter_projector",
        {"hdmi": HdmiOptions, "lightcrafter": LightCrafterOptions},
        Capabilities(sequence_playback=True, power_control=True),
        check=_lightcrafter_fits,
    ),
    DriverEntry(
        "sim",
        DeviceKind.CAMERA,
        "a camera of the simulated bench (free-running, or triggered by a sequence projector)",
        f"{_SIMULATED}:camera",
        {"sim": SimCameraOptions},
        Capabilities(trigger_input=True),
        simulated=True,
    ),
    DriverEntry(
        "v4l2",
        DeviceKind.CAMERA,
        "a V4L2/UVC camera through OpenCV's V4L2 backend",
        f"{_HARDWARE}:v4l2_camera",
        {"v4l2": V4l2Options},
    ),
    DriverEntry(
        "oak",
        DeviceKind.CAMERA,
        "a Luxonis OAK camera through DepthAI, in a worker process (FSIN trigger input)",
        f"{_HARDWARE}:oak_camera",
        {"oak": OakOptions},
        Capabilities(trigger_input=True),
    ),
    DriverEntry(
        "replay",
        DeviceKind.CAMERA,
        "recorded frames (a folder, or memory) played at a set rate: free-running, or one per trigger",
        f"{_HARDWARE}:replay_camera",
        {"replay": ReplayOptions},
        Capabilities(trigger_input=True),
    ),
    DriverEntry(
        "pjlink",
        DeviceKind.POWER,
        "PJLink class 1 over TCP: power, input, A/V mute",
        f"{_HARDWARE}:pjlink_power",
        {"power": PowerOptions},
    ),
    *(
        DriverEntry(
            vendor,
            DeviceKind.POWER,
            f"{vendor.capitalize()} RS-232 command set over a serial port: power, input, blank",
            f"{_HARDWARE}:serial_power",
            {"power": PowerOptions},
        )
        for vendor in ("benq", "epson", "optoma")
    ),
)


def drivers_of(kind: DeviceKind) -> dict[str, DriverEntry]:
    """The entries of one kind of device, by name."""
    return {entry.name: entry for entry in DRIVERS if entry.kind is kind}


def driver(kind: DeviceKind, name: str) -> DriverEntry:
    """The entry of a driver; KeyError for a name the table does not hold."""
    return drivers_of(kind)[name]


def check_device(kind: DeviceKind, device: Any) -> None:
    """The table's checks of one projector or camera config: its driver's sections are given, and
    its sync and power fit the driver's capabilities. Raises ValueError naming the field."""
    entry = driver(kind, device.driver)
    for section in entry.sections:
        if getattr(device, section, None) is None:
            raise ValueError(f"{section}: the {entry.name} driver needs its {section} section")
    if kind is DeviceKind.PROJECTOR:
        if device.sync == "hardware" and not entry.capabilities.sequence_playback:
            raise ValueError(f"sync: a {entry.name} projector cannot play a sequence on its own; use software sync")
        if device.power is not None and not entry.capabilities.power_control:
            raise ValueError(f"power: a {entry.name} projector has no power control to configure")
    if entry.check is not None:
        entry.check(device)
