"""The contract suites (drivers.testing) run against every device the rig can build: each entry of
the driver table, built by its own factory from a config exactly as open_rig builds it, with the
real driver on its protocol fake (pyusb's find, OpenCV's VideoCapture, a pyserial URL, a PJLink
server, the OAK worker's fake backend, SDL's offscreen display). `pytest --rig bench.yaml` also runs
them on the first projector, camera and power control of a real bench."""

from __future__ import annotations

import contextlib
import copy
import os
import shutil
import signal
import tempfile
from pathlib import Path
from typing import Any
from unittest import mock

import cv2
import numpy as np
import pytest
import yaml

from drivers.base import Camera, Device, PowerControl, Projector, ProjectorMode
from drivers.fakes.dlpc350 import FakeLcr4500, finder_for
from drivers.fakes.pjlink import FakePJLinkProjector
from drivers.fakes.v4l2 import FakeVideoCapture
from drivers.faults import Fault, FaultPlan
from drivers.testing import CameraContract, Kit, PowerControlContract, ProjectorContract
from rig.assembly.build import build_devices, geometry_model, world_of
from rig.config import DRIVERS, DeviceKind, RigConfig, config_from_dict, load_config
from rig.config.loading import REPO_CONFIG_DIR
from tests.conftest import small_config_data

SMALL_PROJECTOR = {"resolution": [256, 192], "intrinsics": {"fx": 375.0, "fy": 375.0, "cx": 127.5, "cy": 95.5}}


def _built(data: dict[str, Any], kind: DeviceKind, index: int = 0) -> tuple[Device, Any]:
    """One device of a config, built through the driver table (not opened), and its world."""
    devices, world = _all_built(data)
    return devices[kind][index], world


def _all_built(data: dict[str, Any]) -> tuple[dict[DeviceKind, list[Any]], Any]:
    config = config_from_dict(data, "contract kit")
    world = world_of(
        config,
        [geometry_model(c.geometry, c.resolution) for c in config.cameras],
        [geometry_model(p.geometry, p.resolution) for p in config.projectors],
    )
    extras, projectors, cameras = build_devices(config, world)
    devices: dict[DeviceKind, list[Any]] = {
        DeviceKind.PROJECTOR: projectors,
        DeviceKind.CAMERA: cameras,
        DeviceKind.POWER: [getattr(e, "control", e) for e in extras],  # the control a rig's hold wraps
    }
    return devices, world


def _bench_data(name: str) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load((REPO_CONFIG_DIR / name).read_text())
    projector = data["projectors"][0]
    projector["hdmi"] = {"video_driver": "offscreen"}
    projector.pop("power", None)
    if projector["driver"] == "hdmi":
        projector["resolution"] = SMALL_PROJECTOR["resolution"]
        projector["geometry"]["intrinsics"] = SMALL_PROJECTOR["intrinsics"]
    return data


# --- projectors -----------------------------------------------------------------------------------
class TestSimProjector(ProjectorContract):
    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Projector] | None:
        if plan is not None:
            return None  # the simulated projector has no transport to fail
        device, world = _built(small_config_data(), DeviceKind.PROJECTOR)
        return Kit(device, is_dark=lambda: device.is_dark, now=world.clock.now, wait=world.clock.sleep)  # type: ignore[attr-defined]


class TestSimSequenceProjector(ProjectorContract):
    """The simulated projector with sync: hardware: it plays preloaded sequences."""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Projector] | None:
        if plan is not None:
            return None  # the simulated projector has no transport to fail
        data = small_config_data()
        data["projectors"][0]["sync"] = "hardware"
        device, world = _built(data, DeviceKind.PROJECTOR)
        assert device.mode is ProjectorMode.SEQUENCE
        return Kit(device, is_dark=lambda: device.is_dark, now=world.clock.now, wait=world.clock.sleep)  # type: ignore[attr-defined]


class TestHdmiProjector(ProjectorContract):
    """The display worker on SDL's offscreen driver; a stopped worker is silence, a killed one gone."""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Projector] | None:
        data = _bench_data("bench-hdmi-uvc.yaml")
        data["projectors"][0]["hdmi"]["start_timeout_s"] = 5.0
        device, _ = _built(data, DeviceKind.PROJECTOR)
        kit: Kit[Projector] = Kit(device, timeout_s=2.0, is_dark=lambda: device.is_dark)  # type: ignore[attr-defined]
        if plan is not None:
            signals = {Fault.SILENCE: signal.SIGSTOP, Fault.DISCONNECT: signal.SIGKILL}

            def arm() -> None:
                pid = device.worker_pid  # type: ignore[attr-defined]
                os.kill(pid, signals[plan.fault])
                kit.cleanup.append(lambda: _kill_quietly(pid))

            kit.arm = arm
        return kit


def _kill_quietly(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)


class TestLightCrafterProjector(ProjectorContract):
    """The LightCrafter 4500 as the table builds it (USB control and HDMI input), with pyusb
    finding the DLPC350 protocol fake."""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Projector] | None:
        fake = FakeLcr4500()
        patch = mock.patch("usb.core.find", finder_for(fake))
        patch.start()
        data = _bench_data("bench-lightcrafter-uvc.yaml")
        # hardware sync: patterns go over USB as well as HDMI, so USB faults meet every pattern
        data["projectors"][0].update(sync="hardware", pattern_period_us=8333)
        data["projectors"][0]["lightcrafter"] = {"usb_timeout_s": 0.5}
        data["cameras"][0] = yaml.safe_load((REPO_CONFIG_DIR / "bench-hdmi-oak.yaml").read_text())["cameras"][0]
        device, _ = _built(data, DeviceKind.PROJECTOR)

        def is_dark() -> bool:  # LEDs off, or the DMD showing a black input (what an unplugged USB leaves)
            return fake.dark or device.video.is_dark  # type: ignore[attr-defined]

        kit: Kit[Projector] = Kit(device, timeout_s=0.5, is_dark=is_dark, cleanup=[patch.stop])
        if plan is not None:

            def arm() -> None:  # from the next command on
                if plan.fault is Fault.SILENCE:
                    fake.faults.silent_after = fake.commands
                else:
                    fake.faults.unplug_after = fake.commands

            kit.arm = arm
        return kit


# --- cameras --------------------------------------------------------------------------------------
class TestSimCamera(CameraContract):
    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Camera] | None:
        data = small_config_data()
        data["cameras"][0]["sim"] = {"buffered_frames": 2}
        devices, world = _all_built(data)
        device, projector = devices[DeviceKind.CAMERA][0], devices[DeviceKind.PROJECTOR][0]
        projector.open()  # dark: the camera sees the scene in ambient light
        if plan is not None:
            device.inject(plan)
        return Kit(device, now=world.clock.now, wait=world.clock.sleep, cleanup=[projector.close])


class TestV4l2Camera(CameraContract):
    """The V4L2 driver with OpenCV's VideoCapture replaced by its protocol fake."""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Camera] | None:
        if plan is not None and plan.fault is not Fault.SILENCE:
            return None  # the fake cannot make a /dev node vanish
        fake = FakeVideoCapture(plan=plan)
        patch = mock.patch("cv2.VideoCapture", lambda *args: fake)
        patch.start()
        data = _bench_data("bench-hdmi-uvc.yaml")
        # the fake's exposure_time_absolute stops at 2000 (200 ms), as this config says
        data["cameras"][0]["v4l2"] = {"device": "fake-video0", "max_exposure_us": 200_000.0}
        data["cameras"][0]["resolution"] = [320, 256]
        device, _ = _built(data, DeviceKind.CAMERA)
        return Kit(device, cleanup=[patch.stop])


class TestOakCamera(CameraContract):
    """The OAK driver and its worker process on the worker's fake depthai backend."""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Camera] | None:
        data = _bench_data("bench-hdmi-oak.yaml")
        data["cameras"][0]["oak"] = {"backend": "fake"}
        data["cameras"][0]["resolution"] = [320, 256]
        device, _ = _built(data, DeviceKind.CAMERA)
        patch = mock.patch.dict(os.environ, {"SLRIG_FAKE_OAK": str(plan) if plan else ""})
        patch.start()  # the worker, started at open, inherits it
        return Kit(device, cleanup=[patch.stop])


class TestReplayCamera(CameraContract):
    """The replay driver, built through the table, playing a folder of frames at 30 Hz, free-running
    and holding two of them, as a V4L2 driver does (the other way, a frame per capture, is
    TestReplayCameraByCapture)."""

    advance = "clock"

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Camera] | None:
        folder = Path(tempfile.mkdtemp(prefix="replay-"))
        for k in range(5):
            cv2.imwrite(str(folder / f"frame_{k}.png"), np.full((48, 64), 40 * k, np.uint8))
        data = _bench_data("bench-hdmi-uvc.yaml")  # a real projector's config: a replay camera is no simulation
        data["cameras"][0] |= {"driver": "replay", "resolution": [64, 48]}
        data["cameras"][0].pop("v4l2", None)
        replay = {"source": str(folder), "rate_hz": 30.0, "buffered_frames": 2, "advance": self.advance}
        data["cameras"][0]["replay"] = replay
        device, _ = _built(data, DeviceKind.CAMERA)
        if plan is not None:
            device.inject(plan)  # type: ignore[attr-defined]
        cleanup = [lambda: shutil.rmtree(folder, ignore_errors=True)]
        return Kit(device, buffers=self.advance == "clock", cleanup=cleanup)


class TestReplayCameraByCapture(TestReplayCamera):
    advance = "capture"


# --- power controls -------------------------------------------------------------------------------
def _power_data(section: dict[str, Any]) -> dict[str, Any]:
    data = _bench_data("bench-hdmi-uvc.yaml")
    data["projectors"][0]["power"] = {"timeout_s": 0.3, **section}
    return data


class _SerialPower(PowerControlContract):
    vendor = ""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[PowerControl] | None:
        url = f"simprojector://{self.vendor}" + (f"?fault={plan}" if plan else "")
        device, _ = _built(_power_data({"protocol": self.vendor, "url": url}), DeviceKind.POWER)
        return Kit(device, timeout_s=0.3, is_blanked=lambda: bool(device._port.blanked))  # type: ignore[attr-defined]


class TestBenQPower(_SerialPower):
    vendor = "benq"


class TestEpsonPower(_SerialPower):
    vendor = "epson"


class TestOptomaPower(_SerialPower):
    vendor = "optoma"


class TestPJLinkPower(PowerControlContract):
    def make_kit(self, plan: FaultPlan | None = None) -> Kit[PowerControl] | None:
        server = FakePJLinkProjector(password="bench", plan=plan)
        section = {"protocol": "pjlink", "host": "127.0.0.1", "port": server.port, "password": "bench"}
        device, _ = _built(_power_data(section), DeviceKind.POWER)
        return Kit(device, timeout_s=0.3, is_blanked=lambda: server.muted, input_name="31", cleanup=[server.close])


CONTRACT_RUNS: dict[tuple[DeviceKind, str], type] = {
    (DeviceKind.PROJECTOR, "sim"): TestSimProjector,
    (DeviceKind.PROJECTOR, "hdmi"): TestHdmiProjector,
    (DeviceKind.PROJECTOR, "lightcrafter"): TestLightCrafterProjector,
    (DeviceKind.CAMERA, "sim"): TestSimCamera,
    (DeviceKind.CAMERA, "v4l2"): TestV4l2Camera,
    (DeviceKind.CAMERA, "oak"): TestOakCamera,
    (DeviceKind.CAMERA, "replay"): TestReplayCamera,
    (DeviceKind.POWER, "benq"): TestBenQPower,
    (DeviceKind.POWER, "epson"): TestEpsonPower,
    (DeviceKind.POWER, "optoma"): TestOptomaPower,
    (DeviceKind.POWER, "pjlink"): TestPJLinkPower,
}
CONTRACTS = {
    DeviceKind.PROJECTOR: ProjectorContract,
    DeviceKind.CAMERA: CameraContract,
    DeviceKind.POWER: PowerControlContract,
}


@pytest.mark.parametrize("entry", DRIVERS, ids=lambda e: f"{e.kind}:{e.name}")
def test_every_driver_in_the_table_runs_its_contract(entry: Any) -> None:
    run = CONTRACT_RUNS.get((entry.kind, entry.name))
    assert run is not None, f"the {entry.kind} driver {entry.name!r} has no contract run in {__name__}"
    assert issubclass(run, CONTRACTS[entry.kind])
    kit = run().make_kit()
    try:  # the kit's device is what the table's factory builds for this driver
        assert isinstance(kit.device, {"projector": Projector, "camera": Camera, "power": PowerControl}[entry.kind])
    finally:
        kit.close()


# --- a real bench, with `pytest --rig bench.yaml` ---------------------------------------------------
def _bench_config(request: pytest.FixtureRequest) -> RigConfig:
    path = request.config.getoption("--rig")
    if path is None:
        pytest.skip("real-bench contracts run with `pytest --rig bench.yaml` (a config of real devices)")
    config = load_config(Path(path))
    if config.simulated:
        pytest.skip(f"--rig {path} describes the simulated bench; its devices run the contracts above")
    return config


class _OnTheBench:
    kind = DeviceKind.PROJECTOR

    @pytest.fixture(autouse=True)
    def _bench(self, request: pytest.FixtureRequest) -> None:
        self.bench = _bench_config(request)

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[Any] | None:
        if plan is not None:
            return None  # faults are not injected into real hardware
        data = copy.deepcopy(self.bench.model_dump(mode="json"))
        if self.kind is DeviceKind.POWER and not any(p.get("power") for p in data["projectors"]):
            pytest.skip("the bench has no power control")
        device, _ = _built(data, self.kind)
        power = next((p["power"] for p in data["projectors"] if p.get("power")), None)
        # a real bench's frames and inputs: what its config says, nothing assumed
        return Kit(device, input_name=(power or {}).get("input") or "hdmi", buffers=False)


class TestBenchProjector(_OnTheBench, ProjectorContract):
    kind = DeviceKind.PROJECTOR


class TestBenchCamera(_OnTheBench, CameraContract):
    kind = DeviceKind.CAMERA


class TestBenchPower(_OnTheBench, PowerControlContract):
    kind = DeviceKind.POWER
