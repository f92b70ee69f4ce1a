"""The simulated camera: the real Camera interface over the SimBench model."""

from __future__ import annotations

import time

from drivers.base import Camera, Frame
from drivers.errors import DeviceDisconnectedError, DeviceTimeoutError
from drivers.faults import Fault, FaultPlan
from drivers.options import SimFaults
from drivers.sequences import TriggerMode
from drivers.sim.bench import SimBench


class SimCamera(Camera):
    """A camera that renders the simulated scene under the projectors' current light."""

    has_gain = True
    has_exposure = True

    def __init__(self, name: str, bench: SimBench, index: int, faults: SimFaults | None = None) -> None:
        super().__init__(name)
        self._bench = bench
        self._index = index
        self._params = bench.camera_options[index]
        self._sensor = bench.camera_settings[index]
        self._exposure_us = self._sensor.exposure_us
        self._gain = self._sensor.gain
        self._sequence = 0
        self._captures = 0
        self._faults = faults or bench.camera_options[index].faults

    def inject(self, plan: FaultPlan) -> None:
        """A fault as the protocol fakes take it (drivers.faults), counted in frames."""
        if plan.fault is Fault.SILENCE:
            self._faults = SimFaults(stall_after_frames=plan.after)
        else:
            self._faults = SimFaults(disconnect_after_frames=plan.after)
        self._last: Frame | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        model = self._bench.cameras[self._index]
        return model.width, model.height

    def _do_open(self) -> None:
        self._sequence = 0
        self._captures = 0
        self._last = None
        self._next_trigger = len(self._bench.trigger_times)

    def _do_set_trigger(self, mode: TriggerMode) -> None:
        self._next_trigger = len(self._bench.trigger_times)  # pulses from now on

    def _triggered_time(self, deadline: float) -> float:
        """Bench time of the next trigger pulse; the camera waits (in bench time) until then."""
        if self._next_trigger >= len(self._bench.trigger_times):
            time.sleep(max(0.0, min(0.05, deadline - time.monotonic())))
            raise DeviceTimeoutError(f"{self.name}: no trigger pulse before the capture deadline")
        when = self._bench.trigger_times[self._next_trigger]
        self._next_trigger += 1
        self._bench.clock_s = max(self._bench.clock_s, when)
        return when

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
        if faults.disconnect_after_frames is not None and self._sequence >= faults.disconnect_after_frames:
            raise DeviceDisconnectedError(f"{self.name}: simulated camera disconnected")
        if faults.stall_after_frames is not None and self._sequence >= faults.stall_after_frames:
            self._wait_until(deadline)  # a wedged driver, but one whose wait a cancel cuts
            raise DeviceTimeoutError(f"{self.name}: no frame before the capture deadline")
        if faults.repeat_frame_at is not None and self._captures == faults.repeat_frame_at and self._last is not None:
            return self._last
        if self.trigger is TriggerMode.EXTERNAL:
            exposed = self._triggered_time(deadline)  # one exposure per pulse, nothing buffered
        else:
            # A driver holding `buffered_frames` hands out the oldest: exposed that many periods ago.
            exposed = self._bench.clock_s - self._params.buffered_frames * self._params.frame_period_s
            if faults.early_frame_at == self._captures:  # a driver that kept one more frame than it said
                exposed -= self._params.frame_period_s
        stamp = exposed + self._exposure_us * 1e-6
        gain = self._sensor.gain if self._gain is None else self._gain
        image = self._bench.render(self._index, self._exposure_us, gain, exposed)
        self._sequence += 1
        self._last = Frame(
            image=image,
            timestamp_s=stamp,
            sequence=self._sequence,
            exposure_us=self._exposure_us,
            gain=gain,
            bit_depth=self._sensor.bit_depth,
        )
        return self._last
