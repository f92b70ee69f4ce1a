"""Config sections of the real device drivers (each used when the device's `driver` names it)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class HdmiOptions(_Strict):
    """A projector as a display: which output, through which SDL video driver."""

    display: int = Field(0, ge=0, le=16, description="display index (0 = first output)")
    video_driver: Literal["kmsdrm", "x11", "wayland", "offscreen"] = Field(
        "kmsdrm", description="kmsdrm on a bench without a desktop; offscreen only for tests"
    )
    start_timeout_s: float = Field(10.0, gt=0, le=120)


class LightCrafterOptions(_Strict):
    """A DLP LightCrafter 4500: USB control plus its HDMI video input (the `hdmi` section's output).

    sync software: video mode, a display whose LEDs go off for dark. sync hardware: video-pattern
    mode, `patterns_per_frame` 8-bit patterns per RGB frame played at `pattern_period_us` each,
    TRIG_OUT_1 starting each camera exposure."""

    serial_number: str | None = Field(None, description="USB serial number, when several are attached")
    patterns_per_frame: int = Field(2, ge=1, le=3, description="8-bit patterns per video frame (green, red, blue)")
    video_rate_hz: float = Field(60.0, ge=10, le=120, description="frame rate of the HDMI mode it is fed")
    input_latency_s: float = Field(
        0.05, ge=0.0, le=1.0, description="from a frame presented on HDMI to the controller holding it"
    )
    usb_timeout_s: float = Field(2.0, gt=0, le=30)


class PowerOptions(_Strict):
    """Housekeeping of the projector: switched on with this input at open, blanked at close."""

    protocol: Literal["pjlink", "benq", "epson", "optoma"]
    url: str | None = Field(None, description="serial projectors: a pyserial URL, e.g. /dev/slrig-projector")
    host: str | None = Field(None, description="PJLink: the projector's address")
    port: int = Field(4352, ge=1, le=65535)
    password: str | None = Field(None, max_length=32)
    input: str | None = Field(None, description="input to select: hdmi, hdmi2, vga (serial) or PJLink's code, e.g. 31")
    timeout_s: float = Field(3.0, gt=0, le=60)

    @model_validator(mode="after")
    def _address(self) -> PowerOptions:
        if self.protocol == "pjlink" and not self.host:
            raise ValueError("PJLink needs host")
        if self.protocol != "pjlink" and not self.url:
            raise ValueError(f"{self.protocol} needs url (the serial port)")
        return self


class V4l2Options(_Strict):
    device: str = Field(description="/dev/video0, or better a stable /dev/v4l/by-id/... or udev link")
    pixel_format: str = Field("GREY", min_length=4, max_length=4, description="V4L2 fourcc: GREY, Y16 , YUYV, MJPG")
    buffer_frames: int = Field(2, ge=1, le=8)
    frame_period_s: float = Field(1 / 30, gt=0, le=10)


class OakOptions(_Strict):
    device_id: str | None = Field(None, description="the OAK's id (slrig devices); default: the first found")
    socket: Literal["CAM_A", "CAM_B", "CAM_C", "CAM_D"] = "CAM_B"
    iso: int = Field(400, ge=100, le=1600)
    focus: int | None = Field(None, ge=0, le=255, description="manual lens position (auto-focus modules)")
    fps: float = Field(30.0, gt=0, le=120)
    backend: Literal["depthai", "fake"] = Field("depthai", description="fake: a simulated OAK, for demos and tests")
