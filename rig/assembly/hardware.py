"""The real devices of a rig config: HDMI projectors (with optional power control over PJLink or
RS-232), LightCrafter 4500s (USB control and HDMI input), V4L2 and OAK cameras."""

from __future__ import annotations

from drivers.base import Camera, Device, Projector
from drivers.dlp.hdmi_patterns import LightCrafterHdmiProjector
from drivers.dlp.lcr4500 import Lcr4500Projector
from drivers.hdmi.projector import HdmiProjector
from drivers.oak.camera import OakCamera
from drivers.pjlink import PJLinkProjector
from drivers.serial_projector import SerialProjectorControl
from drivers.v4l2 import V4l2Camera
from rig.config import CameraConfig, ProjectorConfig, RigConfig
from rig.errors import ConfigError


class PowerControl(Device):
    """Switches a projector on with its input selected when opened, blanks it when closed."""

    def __init__(self, name: str, device: SerialProjectorControl | PJLinkProjector, input_name: str | None) -> None:
        super().__init__(name)
        self.device = device
        self.input_name = input_name

    def _do_open(self) -> None:
        self.device.open()
        try:
            self.device.power(True)
            if self.input_name:
                self.device.select_input(self.input_name)
        except Exception:
            self.device.close()
            raise

    def _do_close(self) -> None:
        try:
            self.device.blank(True)
        finally:
            self.device.close()


def projector(config: ProjectorConfig) -> Projector:
    if config.driver not in ("hdmi", "lightcrafter"):
        raise ConfigError("config", [f"projectors: driver {config.driver!r} has no hardware driver"])
    h = config.hdmi
    video = HdmiProjector(config.name, config.resolution, h.display, h.video_driver, start_timeout_s=h.start_timeout_s)
    if config.driver == "hdmi":
        return video
    lc = config.lightcrafter
    control = Lcr4500Projector(f"{config.name}-usb", lc.serial_number, lc.usb_timeout_s)
    return LightCrafterHdmiProjector(
        config.name, control, video, config.sync == "hardware", lc.patterns_per_frame, lc.input_latency_s
    )


def power_control(config: ProjectorConfig) -> PowerControl | None:
    p = config.power
    if p is None:
        return None
    name = f"{config.name}-power"
    device: SerialProjectorControl | PJLinkProjector
    if p.protocol == "pjlink":
        assert p.host is not None
        device = PJLinkProjector(name, p.host, p.port, p.password, p.timeout_s)
    else:
        assert p.url is not None
        device = SerialProjectorControl(name, p.url, p.protocol, p.timeout_s)
    return PowerControl(name, device, p.input)


def camera(config: CameraConfig) -> Camera:
    if config.driver == "v4l2":
        v = config.v4l2
        assert v is not None  # validated
        return V4l2Camera(
            config.name,
            v.device,
            config.resolution,
            v.pixel_format,
            config.exposure_us,
            config.gain,
            v.buffer_frames,
            v.frame_period_s,
            mono=not config.color,
        )
    if config.driver == "oak":
        o = config.oak
        return OakCamera(
            config.name, config.resolution, o.device_id, o.socket, config.exposure_us, o.iso, o.focus, o.fps, o.backend
        )
    raise ConfigError("config", [f"cameras: driver {config.driver!r} has no hardware driver"])


def devices(config: RigConfig) -> tuple[list[Device], list[Projector], list[Camera]]:
    """Housekeeping devices, projectors and cameras of a real rig, not yet opened."""
    extras = [c for c in (power_control(p) for p in config.projectors) if c is not None]
    return extras, [projector(p) for p in config.projectors], [camera(c) for c in config.cameras]
