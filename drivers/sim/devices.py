"""Simulated projector and camera: the real device interfaces over the SimBench model."""

from __future__ import annotations

import time

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
        return self._bench._emitted[self._index] is None

    def _do_open(self) -> None:
        self._bench.set_pattern(self._index, None)

    def _do_show(self, pattern: np.ndarray) -> None:
        self._bench.set_pattern(self._index, pattern)
        self.shown += 1

    def _do_dark(self) -> None:
        self._bench.set_pattern(self._index, None)


class SimCamera(Camera):
    """A camera that renders the simulated scene under the projectors' current light.

    Fault injection for tests: `disconnect_after` frames, then DeviceDisconnectedError;
    `stall_after` frames, then no frame arrives (DeviceTimeoutError at the deadline).
    """

    def __init__(
        self,
        name: str,
        bench: SimBench,
        index: int,
        disconnect_after: int | None = None,
        stall_after: int | None = None,
    ) -> None:
        super().__init__(name)
        self._bench = bench
        self._index = index
        self._params = bench.camera_params[index]
        self._exposure_us = self._params.exposure_us
        self._gain = self._params.gain
        self._sequence = 0
        self._disconnect_after = disconnect_after
        self._stall_after = stall_after

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

    def _do_close(self) -> None:
        pass

    def _do_capture(self, deadline: float) -> Frame:
        if self._disconnect_after is not None and self._sequence >= self._disconnect_after:
            raise DeviceDisconnectedError(f"{self.name}: simulated camera disconnected")
        if self._stall_after is not None and self._sequence >= self._stall_after:
            time.sleep(max(0.0, deadline - time.monotonic()))
            raise DeviceTimeoutError(f"{self.name}: no frame before the capture deadline")
        image = self._bench.render(self._index, self._exposure_us, self._gain)
        self._sequence += 1
        return Frame(
            image=image,
            timestamp_s=self._bench.clock_s,
            sequence=self._sequence,
            exposure_us=self._exposure_us,
            gain=self._gain,
            bit_depth=self._params.bit_depth,
        )
