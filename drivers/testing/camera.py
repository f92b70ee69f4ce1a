"""What every camera promises: numbered, stamped frames of its size; flush drops what the driver
holds; state errors when closed; a silent or vanished camera fails within the capture timeout."""

from __future__ import annotations

import re

import numpy as np
import pytest

from drivers.base import Camera
from drivers.errors import DeviceDisconnectedError, DeviceError, DeviceStateError, DeviceTimeoutError
from drivers.faults import Fault
from drivers.testing.kit import FAULT_GRACE_S, Contract, Kit, fails_within

CAPTURE_TIMEOUT_S = 1.0


class CameraContract(Contract[Camera]):
    def test_frames_are_numbered_timestamped_and_sized(self, kit: Kit[Camera]) -> None:
        camera = kit.device
        camera.open()
        frames = [camera.capture(timeout_s=CAPTURE_TIMEOUT_S) for _ in range(3)]
        assert 1 <= frames[0].sequence < frames[1].sequence < frames[2].sequence
        assert frames[0].timestamp_s < frames[1].timestamp_s < frames[2].timestamp_s
        width, height = camera.resolution
        assert all(f.image.shape[:2] == (height, width) and f.image.dtype in (np.uint8, np.uint16) for f in frames)

    def test_flush_drops_what_the_driver_holds(self, kit: Kit[Camera]) -> None:
        """Frames held by the driver were exposed earlier (stale); after flush() the next frame is
        one the sensor completed after the flush began, and its sequence number shows the frames
        dropped: the contract software sync relies on."""
        camera = kit.device
        camera.open()
        camera.capture(timeout_s=CAPTURE_TIMEOUT_S)
        kit.wait(0.2)  # six frame periods at 30 Hz: every buffer fills
        before = kit.now()
        held = camera.capture(timeout_s=CAPTURE_TIMEOUT_S)
        if kit.buffers:
            assert held.timestamp_s < before  # a naive capture gets an old frame: there is something to drop
        kit.wait(0.2)
        flushed_at = kit.now()
        camera.flush()
        after = camera.capture(timeout_s=CAPTURE_TIMEOUT_S)
        assert after.timestamp_s >= flushed_at
        assert after.sequence > held.sequence

    def test_exposure_is_validated_and_kept(self, kit: Kit[Camera]) -> None:
        camera = kit.device
        camera.open()
        camera.set_exposure_us(5000.0)
        assert camera.exposure_us == 5000.0
        with pytest.raises(ValueError):
            camera.set_exposure_us(0.0)

    def test_an_exposure_outside_the_drivers_range_is_refused_naming_it(self, kit: Kit[Camera]) -> None:
        """Auto-exposure and HDR stay within `exposure_range_us`; a value outside it never reaches the
        device, and the error names the range."""
        camera = kit.device
        camera.open()
        low, high = camera.exposure_range_us
        assert 1.0 <= low < high <= 10_000_000.0
        camera.set_exposure_us(high)
        assert camera.exposure_us == high
        for outside in (high * 1.5, low / 2):
            with pytest.raises(ValueError, match=re.escape(f"{high:g}]")):
                camera.set_exposure_us(outside)
        assert camera.exposure_us == high

    def test_a_frame_carries_the_exposure_it_was_taken_at(self, kit: Kit[Camera]) -> None:
        """What auto-exposure and HDR rely on: a camera that sets its exposure takes the next frames
        at it, and says so in each frame (one without the control says so: has_exposure)."""
        camera = kit.device
        camera.open()
        if not camera.has_exposure:
            pytest.skip(f"{type(camera).__name__} has no exposure control (has_exposure)")
        for exposure_us in (5000.0, 800.0):
            camera.set_exposure_us(exposure_us)
            camera.flush()
            frame = camera.capture(timeout_s=CAPTURE_TIMEOUT_S)
            assert frame.exposure_us == pytest.approx(exposure_us, rel=0.02)

    def test_closed_cameras_refuse_and_close_twice(self, kit: Kit[Camera]) -> None:
        camera = kit.device
        with pytest.raises(DeviceStateError):
            camera.capture()
        camera.open()
        camera.close()
        camera.close()
        with pytest.raises(DeviceStateError):
            camera.capture()

    @pytest.mark.parametrize(
        ("fault", "error"), [(Fault.SILENCE, DeviceTimeoutError), (Fault.DISCONNECT, DeviceDisconnectedError)]
    )
    def test_a_fault_fails_within_the_capture_timeout(self, fault: Fault, error: type[DeviceError]) -> None:
        kit = self.faulty(fault, after=1)
        try:
            camera = kit.device
            camera.open()
            camera.capture(timeout_s=CAPTURE_TIMEOUT_S)
            if kit.arm is not None:
                kit.arm()
            fails_within(CAPTURE_TIMEOUT_S + FAULT_GRACE_S, lambda: camera.capture(timeout_s=CAPTURE_TIMEOUT_S), error)
        finally:
            kit.close()
