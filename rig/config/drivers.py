"""The table of drivers: every `driver:` (and power `protocol:`) a config may name.

Each entry maps a name to the config sections its driver reads (one options model each, from
drivers.options), its capabilities, its factory, what it needs of the machine it runs on and the
USB ids its devices show. Everything per driver derives from this table: the config's driver lists,
its sections (rig.config.equipment) and driver checks, the assembly's devices, simulated ones
included, `slrig doctor`'s checks and `slrig devices`' names. Adding a driver is its module, its
options, its entry here, its protocol fake and its contract run (docs/architecture.md).

Factories and machine checks are named ("module:attribute"), not imported: reading the table, as
every config validation does, loads no driver code, and the simulator (trimesh, Embree) loads only
when a simulated rig is opened. The assembly resolves them (named).
"""

from __future__ import annotations

import enum
import importlib
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
    # "module:attribute": a real driver's takes its device's config (drivers.options.DeviceConfig),
    # a simulated one's (device config, index, world); each returns a Device (a power entry's, its
    # PowerControl)
    factory: str
    sections: Mapping[str, type[BaseModel]] = field(default_factory=dict)  # config section -> its options
    capabilities: Capabilities = Capabilities()
    simulated: bool = False
    check: Callable[[Any], None] | None = None  # further checks of a device config; raises ValueError
    needs: str | None = None  # "module:function": (device config) -> what this machine lacks for it
    usb_ids: Mapping[tuple[int, int], str] = field(default_factory=dict)  # (vendor, product) -> what it is
    given: frozenset[str] = frozenset()  # sections a config must write out (no defaults stand in)


def _lightcrafter_fits(device: Any) -> None:
    if tuple(device.resolution) != LIGHTCRAFTER_RESOLUTION:
        raise ValueError(f"resolution: a LightCrafter 4500 is {list(LIGHTCRAFTER_RESOLUTION)}")
    if device.sync == "hardware":
        device.lightcrafter.check_timing(device.pattern_period_us)


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
        "drivers.hdmi.projector:HdmiProjector.from_config",
        {"hdmi": HdmiOptions},
        Capabilities(power_control=True),
        needs="drivers.hdmi.projector:machine_problems",
    ),
    DriverEntry(
        "lightcrafter",
        DeviceKind.PROJECTOR,
        "TI DLP LightCrafter 4500: USB control (DLPC350) and its HDMI video input",
        "drivers.dlp.hdmi_patterns:LightCrafterHdmiProjector.from_config",
        {"hdmi": HdmiOptions, "lightcrafter": LightCrafterOptions},
        Capabilities(sequence_playback=True, power_control=True),
        check=_lightcrafter_fits,
        needs="drivers.dlp.hdmi_patterns:machine_problems",
        usb_ids={(0x0451, 0x6401): "TI DLP LightCrafter 4500 (DLPC350)"},
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
        "drivers.v4l2:V4l2Camera.from_config",
        {"v4l2": V4l2Options},
        needs="drivers.v4l2:machine_problems",
        given=frozenset({"v4l2"}),
    ),
    DriverEntry(
        "oak",
        DeviceKind.CAMERA,
        "a Luxonis OAK camera through DepthAI, in a worker process (FSIN trigger input)",
        "drivers.oak.camera:OakCamera.from_config",
        {"oak": OakOptions},
        Capabilities(trigger_input=True),
        needs="drivers.oak.camera:machine_problems",
        usb_ids={(0x03E7, 0x2485): "Luxonis OAK (booting)", (0x03E7, 0xF63B): "Luxonis OAK"},
    ),
    DriverEntry(
        "replay",
        DeviceKind.CAMERA,
        "recorded frames (a folder, or memory) played at a set rate: free-running, or one per trigger",
        "drivers.replay:ReplayCamera.from_config",
        {"replay": ReplayOptions},
        Capabilities(trigger_input=True),
        needs="drivers.replay:machine_problems",
        given=frozenset({"replay"}),
    ),
    DriverEntry(
        "pjlink",
        DeviceKind.POWER,
        "PJLink class 1 over TCP: power, input, A/V mute",
        "drivers.pjlink:PJLinkPowerControl.from_config",
        {"power": PowerOptions},
    ),
    *(
        DriverEntry(
            vendor,
            DeviceKind.POWER,
            f"{vendor.capitalize()} RS-232 command set over a serial port: power, input, blank",
            "drivers.serial_projector:SerialPowerControl.from_config",
            {"power": PowerOptions},
            needs="drivers.serial_projector:machine_problems",
        )
        for vendor in ("benq", "epson", "optoma")
    ),
)


def named(reference: str) -> Any:
    """What a "module:attribute" reference of the table names (imported now: only the drivers a
    rig uses load)."""
    module, _, path = reference.partition(":")
    found: Any = importlib.import_module(module)
    for attribute in path.split("."):
        found = getattr(found, attribute)
    return found


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
