"""Factories of the real devices (named by the driver table in rig.config.drivers): HDMI
projectors, LightCrafter 4500s (USB control and HDMI input), V4L2 and OAK cameras, and the power
controls (PJLink, RS-232) that switch a projector on for a rig's life."""

from __future__ import annotations

from drivers.base import Camera, Device, PowerControl, Projector
from drivers.dlp.hdmi_patterns import LightCrafterHdmiProjector
from drivers.dlp.lcr4500 import Lcr4500Projector
from drivers.hdmi.projector import HdmiProjector
from drivers.oak.camera import OakCamera
from drivers.pjlink import PJLinkPowerControl
from drivers.replay import ReplayCamera
from drivers.serial_projector import SerialPowerControl
from drivers.v4l2 import V4l2Camera
from rig.assembly.world import World
from rig.config import CameraConfig, ProjectorConfig


class ProjectorPower(Device):
    """A rig's hold on a projector's power control: switched on with its input selected when
    opened, blanked when closed."""

    def __init__(self, control: PowerControl, input_name: str | None) -> None:
        super().__init__(control.name)
        self.control = control
        self.input_name = input_name

    def _do_open(self) -> None:
        self.control.open()
        try:
            self.control.power(True)
            if self.input_name:
                self.control.select_input(self.input_name)
        except Exception:
            self.control.close()
            raise

    def _do_close(self) -> None:
        try:
            self.control.blank(True)
        finally:
            self.control.close()


def hdmi_projector(config: ProjectorConfig, index: int, world: World) -> Projector:
    h = config.hdmi
    return HdmiProjector(config.name, config.resolution, h.display, h.video_driver, start_timeout_s=h.start_timeout_s)


def lightcrafter_projector(config: ProjectorConfig, index: int, world: World) -> Projector:
    lc = config.lightcrafter
    control = Lcr4500Projector(f"{config.name}-usb", lc.serial_number, lc.usb_timeout_s)
    video = hdmi_projector(config, index, world)
    assert isinstance(video, HdmiProjector)
    return LightCrafterHdmiProjector(
        config.name, control, video, config.sync == "hardware", lc.patterns_per_frame, lc.input_latency_s
    )


def pjlink_power(config: ProjectorConfig, index: int, world: World) -> Device:
    p = config.power
    assert p is not None and p.host is not None  # validated: PJLink needs host
    control = PJLinkPowerControl(f"{config.name}-power", p.host, p.port, p.password, p.timeout_s)
    return ProjectorPower(control, p.input)


def serial_power(config: ProjectorConfig, index: int, world: World) -> Device:
    p = config.power
    assert p is not None and p.url is not None  # validated: serial protocols need url
    return ProjectorPower(SerialPowerControl(f"{config.name}-power", p.url, p.protocol, p.timeout_s), p.input)


def v4l2_camera(config: CameraConfig, index: int, world: World) -> Camera:
    v = config.v4l2
    assert v is not None  # validated: the table requires the v4l2 section
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
        max_exposure_us=v.max_exposure_us,
    )


def oak_camera(config: CameraConfig, index: int, world: World) -> Camera:
    o = config.oak
    return OakCamera(
        config.name, config.resolution, o.device_id, o.socket, config.exposure_us, o.iso, o.focus, o.fps, o.backend
    )


def replay_camera(config: CameraConfig, index: int, world: World) -> Camera:
    r = config.replay
    assert r is not None  # validated: the table requires the replay section
    return ReplayCamera(config.name, config.resolution, r, exposure_us=config.exposure_us, bit_depth=config.bit_depth)
