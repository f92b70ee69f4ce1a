"""Projectors and cameras in a config: driver, size, geometry, and the drivers' own sections.

The driver names, the drivers' sections and the checks that depend on a driver come from the
table in rig.config.drivers: a driver added there adds its section here.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, create_model, model_validator

from drivers.options import CameraSettings, PowerOptions
from rig.config.common import Name, Resolution, Strict
from rig.config.drivers import DeviceKind, check_device, drivers_of
from rig.config.geometry import Geometry

ProjectorDriver = Literal[tuple(drivers_of(DeviceKind.PROJECTOR))]  # type: ignore[valid-type]
CameraDriver = Literal[tuple(drivers_of(DeviceKind.CAMERA))]  # type: ignore[valid-type]
PowerDriver = Literal[tuple(drivers_of(DeviceKind.POWER))]  # type: ignore[valid-type]


class PowerConfig(PowerOptions):
    """A projector's power control; `protocol` names its driver in the table."""

    protocol: PowerDriver  # type: ignore[valid-type]


def driver_sections(kind: DeviceKind) -> dict[str, Any]:
    """Every section a driver of `kind` reads (the table's), as fields: one a driver must be given
    (DriverEntry.given) defaults to None, and the table's check asks for it; the rest default to
    their options' defaults."""
    entries = drivers_of(kind).values()
    fields: dict[str, Any] = {}
    for entry in entries:
        for section, options in entry.sections.items():
            if section in fields:
                continue
            readers = ", ".join(e.name for e in entries if section in e.sections)
            about = f"the {section} section ({readers}): {(options.__doc__ or '').strip().splitlines()[0]}"
            if any(section in e.given for e in entries):
                fields[section] = (options | None, Field(None, description=about))
            else:
                fields[section] = (options, Field(options(), description=about))
    return fields


class _Projector(Strict):
    """A projector: its driver, size and geometry, how patterns are timed, and its power control."""

    name: Name
    driver: ProjectorDriver = "sim"  # type: ignore[valid-type]
    resolution: Resolution
    geometry: Geometry
    latency_s: Annotated[float, Field(ge=0.0, le=2.0)] | Literal["measured"] = Field(
        0.0,
        description="time from show() to the pattern's light on the scene, waited after every pattern; "
        "'measured': the value `slrig doctor --latency` stored in <data_dir>/latency.json",
    )
    sync: Literal["software", "hardware"] = Field(
        "software",
        description="software: show each pattern, wait latency_s, flush, capture; hardware: the projector "
        "plays the whole sequence and its trigger output starts every camera exposure",
    )
    pattern_period_us: int = Field(33334, ge=1000, le=10_000_000, description="pattern period (hardware sync)")
    power: PowerConfig | None = None

    @model_validator(mode="after")
    def _driver_fits(self) -> Any:
        check_device(DeviceKind.PROJECTOR, self)
        return self


class _Camera(CameraSettings, Strict):
    """A camera: its driver, size and geometry, and its settings (exposure, gain, bit depth, colour)."""

    name: Name
    driver: CameraDriver = "sim"  # type: ignore[valid-type]
    resolution: Resolution
    geometry: Geometry

    @model_validator(mode="after")
    def _driver_fits(self) -> Any:
        check_device(DeviceKind.CAMERA, self)
        return self


# Each with a field per driver section of the table (`config.hdmi`, `config.v4l2`, ...).
ProjectorConfig = create_model(
    "ProjectorConfig", __base__=_Projector, __module__=__name__, **driver_sections(DeviceKind.PROJECTOR)
)
CameraConfig = create_model("CameraConfig", __base__=_Camera, __module__=__name__, **driver_sections(DeviceKind.CAMERA))
