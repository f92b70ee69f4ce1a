"""A protocol fake of a V4L2 camera behind OpenCV's VideoCapture API: properties that clamp like
a UVC camera's controls, a sensor free-running on the monotonic clock, the driver's queue of
buffers, and injectable faults. The real drivers.v4l2.V4l2Camera runs against it unchanged.

As in V4L2, a completed frame enters the queue only while a buffer is free: when the application
does not dequeue, the queue keeps the oldest frames and new ones are lost. Buffer stamps are
the end of exposure in milliseconds of CLOCK_MONOTONIC, as uvcvideo gives them.
"""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass

import cv2
import numpy as np

from drivers.faults import Fault, FaultPlan
from drivers.v4l2_controls import refuses


@dataclass
class V4l2Faults:
    absent: bool = False  # cannot be opened
    stall_after: int | None = None  # grabs after this many frames fail (read timeout)
    repeat_at: int | None = None  # this grab hands back the previous buffer again (same timestamp)
    drop_at: int | None = None  # this grab comes two frames late (one frame dropped)
    max_exposure: int = 2000  # exposure_time_absolute range (100 us units), clamped like a UVC camera
    sizes: tuple[tuple[int, int], ...] = ((640, 480), (1280, 1024), (320, 256))


class FakeVideoCapture:
    def __init__(
        self, faults: V4l2Faults | None = None, frame_period_s: float = 1 / 30, plan: FaultPlan | None = None
    ) -> None:
        self.faults = faults or V4l2Faults()
        if plan is not None:  # counted in frames; a V4L2 node that is gone cannot be faked here
            if plan.fault is not Fault.SILENCE:
                raise ValueError(f"the V4L2 fake injects only {Fault.SILENCE}")
            self.faults.stall_after = plan.after
        self.period_ms = frame_period_s * 1000.0
        self.props: dict[int, float] = {
            cv2.CAP_PROP_FRAME_WIDTH: 640,
            cv2.CAP_PROP_FRAME_HEIGHT: 480,
            cv2.CAP_PROP_EXPOSURE: 100,
            cv2.CAP_PROP_AUTO_EXPOSURE: 3,
            cv2.CAP_PROP_GAIN: 0,
            cv2.CAP_PROP_BUFFERSIZE: 4,
        }
        self.sets: list[tuple[int, float]] = []  # every set() the driver made
        self.refused: list[str] = []  # why each refused set() was refused
        self.frames = 0  # grabs answered
        self.stamp_ms = 0.0  # of the buffer last grabbed
        self.released = False
        self._grabbed: np.ndarray | None = None
        self._queue: collections.deque[float] = collections.deque()  # stamps of the filled buffers
        self._next_ms = time.monotonic() * 1000.0 + self.period_ms  # when the sensor completes a frame

    def isOpened(self) -> bool:  # noqa: N802 - OpenCV's name
        return not self.faults.absent and not self.released

    def set(self, prop: int, value: float) -> bool:
        self.sets.append((prop, value))
        reason = refuses(prop, value)
        if reason is not None:  # what V4L2 refuses (EINVAL, ERANGE): OpenCV's set() says False
            self.refused.append(reason)
            return False
        if prop in (cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT):
            other = cv2.CAP_PROP_FRAME_HEIGHT if prop == cv2.CAP_PROP_FRAME_WIDTH else cv2.CAP_PROP_FRAME_WIDTH
            wanted = (value, self.props[other]) if prop == cv2.CAP_PROP_FRAME_WIDTH else (self.props[other], value)
            if any(w == wanted[0] for w, _ in self.faults.sizes):
                self.props[prop] = value
            return True
        if prop == cv2.CAP_PROP_EXPOSURE:
            value = float(min(max(value, 1), self.faults.max_exposure))
        self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        if prop == cv2.CAP_PROP_POS_MSEC:
            return self.stamp_ms
        return float(self.props.get(prop, 0.0))

    def grab(self) -> bool:
        if self.released:
            return False
        f = self.faults
        if f.stall_after is not None and self.frames >= f.stall_after:
            return False
        self.frames += 1
        if f.repeat_at is not None and self.frames == f.repeat_at and self._grabbed is not None:
            return True  # the same buffer, the same timestamp
        if f.drop_at == self.frames:
            self._dequeue()  # this frame is lost: the next one is handed out
        self.stamp_ms = self._dequeue()
        width, height = int(self.props[cv2.CAP_PROP_FRAME_WIDTH]), int(self.props[cv2.CAP_PROP_FRAME_HEIGHT])
        image = np.full((height, width, 3), self.frames % 256, np.uint8)  # brightness encodes the frame
        self._grabbed = image
        return True

    def _fill(self) -> None:
        """Frames the sensor completed since the last look go into free buffers; the rest are lost."""
        now_ms = time.monotonic() * 1000.0
        while self._next_ms <= now_ms:
            if len(self._queue) < max(1, int(self.props[cv2.CAP_PROP_BUFFERSIZE])):
                self._queue.append(self._next_ms)
            self._next_ms += self.period_ms

    def _dequeue(self) -> float:
        """The oldest filled buffer's stamp, waiting for the sensor when none is filled (DQBUF)."""
        self._fill()
        if not self._queue:
            time.sleep(max(0.0, self._next_ms / 1000.0 - time.monotonic()))
            self._fill()
        return self._queue.popleft()

    def retrieve(self) -> tuple[bool, np.ndarray | None]:
        return (self._grabbed is not None), self._grabbed

    def release(self) -> None:
        self.released = True
