"""Projectors and cameras in a config: driver, size, geometry, and the driver's own sections.

The driver names and the checks that depend on a driver come from the table in rig.config.drivers.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from drivers.options import (
    CameraSettings,
    HdmiOptions,
    LightCrafterOptions,
    OakOptions,
    PowerOptions,
    ReplayOptions,
    SimCameraOptions,
    SimProjectorOptions,
    V4l2Options,
)
from rig.config.common import Name, Resolution, Strict
from rig.config.drivers import DeviceKind, check_device, drivers_of
from rig.config.geometry import Geometry

ProjectorDriver = Literal[tuple(drivers_of(DeviceKind.PROJECTOR))]  # type: ignore[valid-type]
CameraDriver = Literal[tuple(drivers_of(DeviceKind.CAMERA))]  # type: ignore[valid-type]
PowerDriver = Literal[tuple(drivers_of(DeviceKind.POWER))]  # type: ignore[valid-type]


class PowerConfig(PowerOptions):
    """A projector's power control; `protocol` names its driver in the table."""

    protocol: PowerDriver  # type: ignore[valid-type]


class ProjectorConfig(Strict):
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
    sim: SimProjectorOptions = SimProjectorOptions()
    hdmi: HdmiOptions = HdmiOptions()
    lightcrafter: LightCrafterOptions = LightCrafterOptions()
    power: PowerConfig | None = None

    @model_validator(mode="after")
    def _driver_fits(self) -> ProjectorConfig:
        check_device(DeviceKind.PROJECTOR, self)
        return self


class CameraConfig(CameraSettings, Strict):
    name: Name
    driver: CameraDriver = "sim"  # type: ignore[valid-type]
    resolution: Resolution
    geometry: Geometry
    sim: SimCameraOptions = SimCameraOptions()
    v4l2: V4l2Options | None = Field(
        None, description="the v4l2 driver's section (at least device: /dev/video0 or a stable link)"
    )
    oak: OakOptions = OakOptions()
    replay: ReplayOptions | None = Field(
        None, description="the replay driver's section: the folder of recorded frames and the rate they play at"
    )

    @model_validator(mode="after")
    def _driver_fits(self) -> CameraConfig:
        check_device(DeviceKind.CAMERA, self)
        return self
