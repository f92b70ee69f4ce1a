"""The settings of every driver, as a rig config spells them: one pydantic model per config section.

The drivers take these models themselves (the simulator its `sim` sections, the assembly hands the
real drivers theirs), so each setting is defined once. Every model forbids unknown keys and bounds
every number. Nothing here imports a driver: reading a config loads no device code.
"""

from __future__ import annotations

from typing import Any, Literal, Protocol

from pydantic import BaseModel, ConfigDict, Field, model_validator

LIGHTCRAFTER_RESOLUTION = (912, 1140)  # DLPC350 native (diamond) resolution
LIGHTCRAFTER_MIN_8BIT_PERIOD_US = 8333  # 8-bit patterns at up to 120 Hz (LightCrafter 4500 user guide, DLPU011)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class DeviceConfig(Protocol):
    """What a driver's factory and machine check read of its device's config (rig.config's
    ProjectorConfig or CameraConfig): its name, its size, and every section by its name
    (`device.v4l2`, `device.power`; a camera's CameraSettings too)."""

    @property
    def name(self) -> str: ...

    @property
    def resolution(self) -> tuple[int, int]: ...

    def __getattr__(self, section: str) -> Any: ...


class CameraSettings(_Strict):
    """What every camera is set to, whatever its driver."""

    exposure_us: float = Field(10000.0, ge=1.0, le=1e7)
    gain: float = Field(1.0, ge=0.0, le=64.0)
    bit_depth: Literal[8, 10, 12, 16] = 8
    color: bool = Field(False, description="colour sensor (BGR frames); decoding uses their luminance")

    @property
    def full_scale(self) -> int:
        """The largest count of one of its samples (bit_depth bits): what decoders divide by."""
        return (1 << self.bit_depth) - 1


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

    def check_timing(self, period_us: int) -> None:
        """8-bit patterns run at up to 120 Hz (LightCrafter 4500 user guide) and a video frame's
        patterns must fit in its period; ValueError naming pattern_period_us otherwise."""
        if period_us < LIGHTCRAFTER_MIN_8BIT_PERIOD_US:
            raise ValueError(f"pattern_period_us: 8-bit patterns need at least {LIGHTCRAFTER_MIN_8BIT_PERIOD_US} us")
        frame_us = 1e6 / self.video_rate_hz
        if self.patterns_per_frame * period_us > frame_us:
            raise ValueError(
                f"pattern_period_us: {self.patterns_per_frame} patterns of {period_us} us do not fit in a "
                f"{self.video_rate_hz:g} Hz video frame ({frame_us:.0f} us); use at most "
                f"{int(frame_us // self.patterns_per_frame)} us or fewer lightcrafter.patterns_per_frame"
            )


class PowerOptions(_Strict):
    """Housekeeping of the projector: switched on with this input at open, blanked at close."""

    protocol: str = Field(min_length=1, max_length=32, description="the power driver: pjlink, benq, epson, optoma")
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
    """A V4L2/UVC camera (drivers.v4l2): at least its device node, /dev/video0 or a stable link."""

    device: str = Field(description="/dev/video0, or better a stable /dev/v4l/by-id/... or udev link")
    pixel_format: str = Field("GREY", min_length=4, max_length=4, description="V4L2 fourcc: GREY, Y16 , YUYV, MJPG")
    buffer_frames: int = Field(2, ge=1, le=8)
    frame_period_s: float = Field(1 / 30, gt=0, le=10)
    max_exposure_us: float = Field(
        1_000_000.0,
        ge=100.0,
        le=1e7,
        description="the camera's longest manual exposure, microseconds (exposure_time_absolute's maximum x 100, "
        "as `v4l2-ctl -d DEVICE -l` lists it); auto-exposure and HDR stay within it",
    )


class ReplayOptions(_Strict):
    """The replay camera's source and pace (drivers.replay)."""

    source: str | None = Field(
        None, description="the folder of recorded frames (relative paths: to the config file); null: frames in memory"
    )
    files: str = Field("*", min_length=1, max_length=200, description="which of the folder's images, a glob")
    rate_hz: float = Field(30.0, gt=0.0, le=1000.0, description="frames per second, as the camera would deliver them")
    loop: bool = Field(True, description="start again after the last frame (else the camera falls silent)")
    buffered_frames: int = Field(0, ge=0, le=8, description="frames the driver holds, as a V4L2 driver does")
    advance: Literal["capture", "clock"] = Field(
        "capture",
        description="capture: each capture takes the source's next frame (no sooner than a frame period after the "
        "last), so a scan's patterns meet the frames recorded for them; clock: free-running, frame k at k / rate",
    )


class OakOptions(_Strict):
    """A Luxonis OAK camera (drivers.oak): which device and socket, and its sensor's settings."""

    device_id: str | None = Field(None, description="the OAK's id (slrig devices); default: the first found")
    socket: Literal["CAM_A", "CAM_B", "CAM_C", "CAM_D"] = "CAM_B"
    iso: int = Field(400, ge=100, le=1600)
    focus: int | None = Field(None, ge=0, le=255, description="manual lens position (auto-focus modules)")
    fps: float = Field(30.0, gt=0, le=120)
    backend: Literal["depthai", "fake"] = Field("depthai", description="fake: a simulated OAK, for demos and tests")


class SimProjectorOptions(_Strict):
    """Photometry and timing of a simulated projector."""

    gamma: float = Field(2.2, ge=0.2, le=5.0, description="pattern value v in [0, 1] emits v ** gamma")
    brightness: float = Field(1.0, gt=0.0, le=100.0, description="white irradiance at 600 mm, relative")
    black_level: float = Field(0.004, ge=0.0, le=0.5, description="light leaked at black, a fraction of white")
    blur_px: float = Field(0.5, ge=0.0, le=20.0, description="defocus, Gaussian sigma in projector pixels")
    latency_s: float = Field(0.0, ge=0.0, le=2.0, description="the simulated projector's true display latency")


class SimFaults(_Strict):
    """Faults to inject, for testing what a rig does when a camera fails (counted in frames)."""

    disconnect_after_frames: int | None = Field(None, ge=0, le=10_000_000)
    stall_after_frames: int | None = Field(None, ge=0, le=10_000_000)
    repeat_frame_at: int | None = Field(None, ge=1, le=10_000_000, description="this capture is a stale repeat")
    early_frame_at: int | None = Field(
        None, ge=1, le=10_000_000, description="this capture was exposed before the last flush (a frame too many held)"
    )


class SimCameraOptions(_Strict):
    """The sensor model of a simulated camera (exposure, gain and bit depth are the camera's own)."""

    full_scale_exposure_us: float = Field(
        12000.0, gt=0.0, le=1e7, description="albedo 1 under irradiance 1 fills the well at this exposure"
    )
    full_well_e: float = Field(10000.0, ge=10.0, le=1e7)
    read_noise_e: float = Field(20.0, ge=0.0, le=1e4)
    gamma: float = Field(1.0, ge=0.2, le=5.0, description="output = signal ** (1 / gamma)")
    blur_px: float = Field(0.6, ge=0.0, le=20.0, description="optical blur, Gaussian sigma in camera pixels")
    frame_period_s: float = Field(1 / 30, gt=0.0, le=10.0)
    buffered_frames: int = Field(0, ge=0, le=16, description="frames the simulated driver holds (stale on capture)")
    faults: SimFaults = SimFaults()
