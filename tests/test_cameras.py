"""The contract every camera keeps is in drivers.testing (run by tests/test_contracts.py);
here, what is particular to each driver."""

from __future__ import annotations

import platform
import time

import cv2
import pytest

from drivers.base import Camera
from drivers.errors import DeviceError, DeviceNotFoundError, DeviceProtocolError, DeviceTimeoutError
from drivers.fakes.v4l2 import FakeVideoCapture, V4l2Faults
from drivers.oak.camera import OakCamera
from drivers.options import SimCameraOptions, SimFaults
from drivers.sim import scene as sc
from drivers.sim.bench import SimBench
from drivers.sim.camera import SimCamera
from drivers.sim.projector import SimProjector
from drivers.v4l2 import V4l2Camera
from tests.conftest import make_device

SIZE = (320, 256)


def _sim(faults: SimFaults | None = None) -> Camera:
    camera = make_device(*SIZE, 450.0, (0.0, 0.0, 600.0))
    projector = make_device(64, 48, 90.0, (100.0, 0.0, 600.0))
    bench = SimBench(
        sc.build_scene([sc.plane(1000.0)]), [camera], [projector], camera_options=[SimCameraOptions(buffered_frames=2)]
    )
    SimProjector("p", bench, 0).open()
    return SimCamera("sim", bench, 0, faults)


def _v4l2(faults: V4l2Faults | None = None, **kwargs: object) -> V4l2Camera:
    fake = FakeVideoCapture(faults)
    return V4l2Camera("v4l2", "fake-video0", SIZE, capture_factory=lambda device: fake, **kwargs)  # type: ignore[arg-type]


def _oak(faults: str = "") -> OakCamera:
    """The real OAK driver and worker process, on the worker's fake depthai backend."""
    return OakCamera("oak", SIZE, backend="fake", env={"SLRIG_FAKE_OAK": faults})


# --- V4L2 specifics ------------------------------------------------------------------------------
def test_v4l2_settings_reach_the_device_in_its_units() -> None:
    fake = FakeVideoCapture()
    camera = V4l2Camera(
        "v4l2", "fake", SIZE, pixel_format="YUYV", exposure_us=12300.0, gain=4.0, capture_factory=lambda device: fake
    )
    with camera:
        assert fake.props[cv2.CAP_PROP_EXPOSURE] == 123  # 100 us units
        assert fake.props[cv2.CAP_PROP_AUTO_EXPOSURE] == 1  # manual
        assert fake.props[cv2.CAP_PROP_GAIN] == 4.0
        assert fake.props[cv2.CAP_PROP_FOURCC] == cv2.VideoWriter_fourcc(*"YUYV")
    assert fake.released


def test_v4l2_refuses_what_the_camera_clamps() -> None:
    with pytest.raises(DeviceError, match=r"exposure .* was not taken"):
        _v4l2(V4l2Faults(max_exposure=50), exposure_us=20000.0).open()
    with pytest.raises(DeviceError, match="width"):
        V4l2Camera("v4l2", "fake", (1000, 700), capture_factory=lambda d: FakeVideoCapture()).open()
    with pytest.raises(DeviceNotFoundError):
        _v4l2(V4l2Faults(absent=True)).open()
    with pytest.raises(DeviceNotFoundError, match="does not exist"):
        V4l2Camera("v4l2", "/dev/video-that-is-not-there", SIZE).open()


def test_v4l2_stale_and_dropped_frames() -> None:
    with _v4l2(V4l2Faults(repeat_at=3)) as camera:
        camera.capture()
        camera.capture()
        with pytest.raises(DeviceProtocolError, match="stale"):
            camera.capture()
    with _v4l2(V4l2Faults(drop_at=3)) as camera:
        frames = [camera.capture() for _ in range(4)]
        assert frames[-1].meta["dropped_before"] == 1


# --- OAK specifics -------------------------------------------------------------------------------
def test_oak_worker_faults_become_device_errors() -> None:
    import os
    import signal

    from drivers.errors import DeviceDisconnectedError

    with pytest.raises(DeviceNotFoundError, match="no OAK"):
        _oak("absent").open()
    for faults in ("xlink_after=1", "abort_after=1"):  # a link error; a native abort of the worker
        with _oak(faults) as camera:
            camera.capture(timeout_s=1.0)
            with pytest.raises(DeviceDisconnectedError):
                camera.capture(timeout_s=1.0)
    with _oak() as camera:
        camera.capture(timeout_s=1.0)
        assert camera.worker_pid is not None
        os.kill(camera.worker_pid, signal.SIGKILL)
        start = time.monotonic()
        with pytest.raises(DeviceDisconnectedError, match=r"exited|not running|gone"):
            camera.capture(timeout_s=1.0)
        assert time.monotonic() - start < 1.5


DEPTHAI_WHEELS = ("x86_64", "aarch64", "AMD64", "arm64")  # where Luxonis publishes wheels (pyproject's oak extra)


def test_oak_with_the_real_depthai_and_no_device_is_not_found() -> None:
    if platform.machine() not in DEPTHAI_WHEELS:
        pytest.skip(f"depthai publishes no wheel for {platform.machine()}; the fake backend's tests run instead")
    import depthai  # noqa: F401  # the test extra installs it here: missing is a failure, not a skip

    camera = OakCamera("oak", SIZE, backend="depthai", env={"DEPTHAI_SEARCH_TIMEOUT": "1000"})
    with pytest.raises(DeviceNotFoundError):
        camera.open()


def test_oak_late_answer_is_never_taken_for_the_next_frame() -> None:
    from drivers.errors import DeviceDisconnectedError

    with _oak("slow_after=1") as camera:
        camera.capture(timeout_s=1.0)
        with pytest.raises(DeviceTimeoutError):
            camera.capture(timeout_s=0.3)  # its answer comes late ...
        with pytest.raises(DeviceDisconnectedError, match="not running"):
            camera.capture(timeout_s=0.3)  # ... so the worker was abandoned, not read out of step


# --- gain, as the console sets it ----------------------------------------------------------------
def test_gain_reaches_each_driver_that_has_it_and_one_without_says_so() -> None:
    fake = FakeVideoCapture()
    with V4l2Camera("v4l2", "fake", SIZE, capture_factory=lambda device: fake) as v4l2:
        v4l2.set_gain(6.0)
        assert fake.props[cv2.CAP_PROP_GAIN] == 6.0 and v4l2.capture().gain == 6.0
    sim = _sim()
    with sim:
        dim = float(sim.capture().image.mean())
        sim.set_gain(4.0)
        frame = sim.capture()
        assert frame.gain == 4.0 and float(frame.image.mean()) > 2.5 * dim  # the sensor model amplifies
    with _oak() as oak:
        oak.set_gain(2.0)
        assert oak.iso == 200 and oak.capture().gain == 2.0
    with pytest.raises(ValueError, match="gain must be in"):
        sim.set_gain(100.0)

    class NoGain(SimCamera):
        has_gain = False

    with pytest.raises(DeviceError, match="no gain control"):
        NoGain("plain", sim._bench, 0).set_gain(2.0)
