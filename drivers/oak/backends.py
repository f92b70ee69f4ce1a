"""What the OAK worker process drives: depthai 3.x (the only module that imports it), or a fake
that behaves like it, including its failures, for tests."""

from __future__ import annotations

import datetime as dt
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.faults import Fault, FaultPlan


class BackendError(Exception):
    """A backend failure; `kind` is notfound, timeout, disconnected or protocol."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class OakSettings:
    device_id: str | None
    socket: str
    width: int
    height: int
    fps: float
    exposure_us: int
    iso: int
    focus: int | None
    external_trigger: bool


class DepthaiBackend:
    """One camera socket of an OAK as a mono stream with manual exposure (depthai 3.x API:
    Pipeline, node.Camera.build(socket).requestOutput, output and input queues)."""

    def __init__(self, s: OakSettings) -> None:
        os.environ.setdefault("DEPTHAI_SEARCH_TIMEOUT", "3000")  # the default search takes 11 s
        device_id = s.device_id
        import depthai as dai  # type: ignore[import-not-found]

        self._dai = dai
        available = dai.Device.getAllAvailableDevices()
        if not available or (device_id and all(d.getDeviceId() != device_id for d in available)):
            raise BackendError(
                "notfound", f"no OAK{' ' + device_id if device_id else ''} attached ({len(available)} found)"
            )
        try:
            device = dai.Device(dai.DeviceInfo(device_id)) if device_id else dai.Device()
            self._pipeline = dai.Pipeline(device)
            camera = self._pipeline.create(dai.node.Camera).build(getattr(dai.CameraBoardSocket, s.socket))
            camera.initialControl.setManualExposure(s.exposure_us, s.iso)
            if s.focus is not None:
                camera.initialControl.setManualFocus(s.focus)
            if s.external_trigger:
                camera.initialControl.setFrameSyncMode(dai.CameraControl.FrameSyncMode.INPUT)
                camera.initialControl.setExternalTrigger(1, 0)
            output = camera.requestOutput((s.width, s.height), dai.ImgFrame.Type.GRAY8, fps=s.fps)
            self._frames = output.createOutputQueue(maxSize=4, blocking=False)
            self._control = camera.inputControl.createInputQueue()
            self._pipeline.start()
        except RuntimeError as exc:
            raise BackendError("notfound", f"cannot start the OAK: {exc}") from exc

    def set_exposure(self, exposure_us: int, iso: int) -> None:
        control = self._dai.CameraControl()
        control.setManualExposure(exposure_us, iso)
        self._control.send(control)

    def frame(self, timeout_s: float) -> tuple[np.ndarray, int, float, float]:
        """Image, sequence number, timestamp (the host's monotonic clock), exposure in us."""
        try:
            message = self._frames.get(dt.timedelta(seconds=timeout_s))
        except RuntimeError as exc:  # XLinkReadError and friends: the device went away
            raise BackendError("disconnected", f"OAK link failed: {exc}") from exc
        except Exception as exc:  # dai.MessageQueue.QueueException (not a RuntimeError)
            raise BackendError("disconnected", f"OAK queue closed: {exc}") from exc
        if message is None:
            raise BackendError("timeout", f"no frame within {timeout_s:g} s")
        stamp = message.getTimestamp().total_seconds()
        return (
            message.getFrame(),
            int(message.getSequenceNum()),
            stamp,
            float(message.getExposureTime().total_seconds() * 1e6),
        )

    def drain(self) -> int:
        return len(self._frames.tryGetAll() or [])

    def close(self) -> None:
        self._pipeline.stop()


class FakeBackend:
    """Behaves like DepthaiBackend on a free-running camera, with depthai's failures on request
    (SLRIG_FAKE_OAK: comma-separated absent, stall_after=N, xlink_after=N, abort_after=N,
    slow_after=N: from then on each frame comes 2.5 s late; or a FaultPlan such as silence@1)."""

    def __init__(self, s: OakSettings) -> None:
        self.faults: dict[str, Any] = {}
        for item in filter(None, os.environ.get("SLRIG_FAKE_OAK", "").split(",")):
            if "@" in item:  # a FaultPlan (drivers.faults), counted in frames
                plan = FaultPlan.parse(item)
                self.faults["stall_after" if plan.fault is Fault.SILENCE else "xlink_after"] = plan.after
                continue
            key, _, value = item.partition("=")
            self.faults[key] = int(value) if value else True
        if self.faults.get("absent"):
            raise BackendError("notfound", "no OAK attached (0 found)")
        self.width, self.height, self.period = s.width, s.height, 1.0 / s.fps
        self.exposure_us = s.exposure_us
        self.sequence = 0  # frames the sensor completed
        self.delivered = 0  # frames handed out; faults count these
        self.next_stamp = time.monotonic() + self.period  # end of the exposure under way
        self.queue: list[tuple[int, float]] = []  # like the depthai output queue: maxSize 4, not blocking

    def set_exposure(self, exposure_us: int, iso: int) -> None:
        self.exposure_us = exposure_us

    def frame(self, timeout_s: float) -> tuple[np.ndarray, int, float, float]:
        f = self.faults
        if "stall_after" in f and self.delivered >= f["stall_after"]:
            time.sleep(timeout_s)
            raise BackendError("timeout", f"no frame within {timeout_s:g} s")
        if "xlink_after" in f and self.delivered >= f["xlink_after"]:
            raise BackendError("disconnected", "OAK link failed: X_LINK_ERROR (XLinkReadError)")
        if "slow_after" in f and self.delivered >= f["slow_after"]:
            time.sleep(timeout_s + 2.5)  # answers, but after the caller (who allows 2 s more) gave up
        if "abort_after" in f and self.delivered >= f["abort_after"]:
            os.abort()  # what a native X_LINK_ERROR does to a depthai process (exit -6)
        self._fill()
        if not self.queue:
            time.sleep(max(0.0, min(timeout_s, self.next_stamp - time.monotonic())))
            self._fill()
            if not self.queue:
                raise BackendError("timeout", f"no frame within {timeout_s:g} s")
        sequence, stamp = self.queue.pop(0)
        self.delivered += 1
        image = np.full((self.height, self.width), (sequence * 37) % 256, np.uint8)
        return image, sequence, stamp, float(self.exposure_us)

    def _fill(self) -> None:
        """Frames completed since the last look enter the queue, which keeps the newest four."""
        now = time.monotonic()
        while self.next_stamp <= now:
            self.sequence += 1
            self.queue.append((self.sequence, self.next_stamp))
            self.next_stamp += self.period
        del self.queue[:-4]

    def drain(self) -> int:
        self._fill()
        dropped, self.queue = len(self.queue), []
        return dropped

    def close(self) -> None:
        pass


BACKENDS = {"depthai": DepthaiBackend, "fake": FakeBackend}
