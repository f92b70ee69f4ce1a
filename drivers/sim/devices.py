"""Simulated projector and camera: the real device interfaces over the SimBench model."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from drivers.base import Camera, Frame, Projector, ProjectorMode
from drivers.errors import DeviceDisconnectedError, DeviceTimeoutError
from drivers.sim.bench import SimBench


class SimProjector(Projector):
    """A streaming projector whose light falls on the simulated scene."""

    mode = ProjectorMode.STREAMING

    def __init__(self, name: str, bench: SimBench, index: int) -> None:
        super().__init__(name)
        self._bench = bench
        self._index = index
        self.shown = 0  # patterns shown since open, for tests

    @property
    def resolution(self) -> tuple[int, int]:
        model = self._bench.projectors[self._index]
        return model.width, model.height

    @property
    def is_dark(self) -> bool:
        """Dark once its latency has passed: no light is on its way."""
        return self._bench._history[self._index][-1][1] is None

    def _do_open(self) -> None:
        self._bench.set_pattern(self._index, None)

    def _do_show(self, pattern: np.ndarray) -> None:
        self._bench.set_pattern(self._index, pattern)
        self.shown += 1

    def _do_dark(self) -> None:
        self._bench.set_pattern(self._index, None)


@dataclass(frozen=True)
class SimCameraFaults:
    """Faults a simulated camera can inject, counted in frames delivered since open."""

    disconnect_after: int | None = None  # then DeviceDisconnectedError
    stall_after: int | None = None  # then no frame arrives: DeviceTimeoutError at the deadline
    repeat_at: int | None = None  # this capture hands back the previous frame again (stale)


class SimCamera(Camera):
    """A camera that renders the simulated scene under the projectors' current light."""

    def __init__(self, name: str, bench: SimBench, index: int, faults: SimCameraFaults | None = None) -> None:
        super().__init__(name)
        self._bench = bench
        self._index = index
        self._params = bench.camera_params[index]
        self._exposure_us = self._params.exposure_us
        self._gain = self._params.gain
        self._sequence = 0
        self._captures = 0
        self._faults = faults or SimCameraFaults()
        self._last: Frame | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        model = self._bench.cameras[self._index]
        return model.width, model.height

    @property
    def exposure_us(self) -> float:
        return self._exposure_us

    def set_exposure_us(self, exposure_us: float) -> None:
        if not 1.0 <= exposure_us <= 10_000_000.0:
            raise ValueError(f"{self.name}: exposure_us must be in [1, 1e7], got {exposure_us}")
        self._exposure_us = float(exposure_us)

    def _do_open(self) -> None:
        self._sequence = 0
        self._captures = 0
        self._last = None

    def _do_close(self) -> None:
        pass

    def _do_flush(self) -> None:
        """Drop the buffered frames: the camera runs on for that many frame periods."""
        skipped = self._params.buffered_frames
        self._bench.advance(skipped * self._params.frame_period_s)
        self._sequence += skipped

    def _do_capture(self, deadline: float) -> Frame:
        faults = self._faults
        self._captures += 1
        if faults.disconnect_after is not None and self._sequence >= faults.disconnect_after:
            raise DeviceDisconnectedError(f"{self.name}: simulated camera disconnected")
        if faults.stall_after is not None and self._sequence >= faults.stall_after:
            time.sleep(max(0.0, deadline - time.monotonic()))
            raise DeviceTimeoutError(f"{self.name}: no frame before the capture deadline")
        if faults.repeat_at is not None and self._captures == faults.repeat_at and self._last is not None:
            return self._last
        # A driver holding `buffered_frames` hands out the oldest: exposed that many periods ago.
        stale_by = self._params.buffered_frames * self._params.frame_period_s
        image = self._bench.render(self._index, self._exposure_us, self._gain, self._bench.clock_s - stale_by)
        self._sequence += 1
        self._last = Frame(
            image=image,
            timestamp_s=self._bench.clock_s,
            sequence=self._sequence,
            exposure_us=self._exposure_us,
            gain=self._gain,
            bit_depth=self._params.bit_depth,
        )
        return self._last
