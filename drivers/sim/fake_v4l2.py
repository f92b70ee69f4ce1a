"""A protocol fake of a V4L2 camera behind OpenCV's VideoCapture API: properties that clamp like
a UVC camera's controls, a free-running frame clock, and injectable faults. The real
drivers.v4l2.V4l2Camera runs against it unchanged."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class V4l2Faults:
    absent: bool = False  # cannot be opened
    stall_after: int | None = None  # grabs after this many frames fail (read timeout)
    repeat_at: int | None = None  # this grab hands back the previous buffer again (same timestamp)
    drop_at: int | None = None  # this grab comes two frames late (one frame dropped)
    max_exposure: int = 2000  # exposure_time_absolute range (100 us units), clamped like a UVC camera
    sizes: tuple[tuple[int, int], ...] = ((640, 480), (1280, 1024), (320, 256))


class FakeVideoCapture:
    def __init__(self, faults: V4l2Faults | None = None, frame_period_s: float = 1 / 30) -> None:
        self.faults = faults or V4l2Faults()
        self.period_ms = frame_period_s * 1000.0
        self.props: dict[int, float] = {
            cv2.CAP_PROP_FRAME_WIDTH: 640,
            cv2.CAP_PROP_FRAME_HEIGHT: 480,
            cv2.CAP_PROP_EXPOSURE: 100,
            cv2.CAP_PROP_AUTO_EXPOSURE: 3,
            cv2.CAP_PROP_GAIN: 0,
            cv2.CAP_PROP_BUFFERSIZE: 4,
        }
        self.frames = 0
        self.stamp_ms = 1000.0
        self.released = False
        self._grabbed: np.ndarray | None = None

    def isOpened(self) -> bool:  # noqa: N802 - OpenCV's name
        return not self.faults.absent and not self.released

    def set(self, prop: int, value: float) -> bool:
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
        self.stamp_ms += self.period_ms * (2 if f.drop_at == self.frames else 1)
        width, height = int(self.props[cv2.CAP_PROP_FRAME_WIDTH]), int(self.props[cv2.CAP_PROP_FRAME_HEIGHT])
        image = np.full((height, width, 3), self.frames % 256, np.uint8)  # brightness encodes the frame
        self._grabbed = image
        return True

    def retrieve(self) -> tuple[bool, np.ndarray | None]:
        return (self._grabbed is not None), self._grabbed

    def release(self) -> None:
        self.released = True
