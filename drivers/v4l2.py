"""V4L2 / UVC cameras through OpenCV's V4L2 backend.

Manual exposure is set in microseconds and sent in V4L2's units (exposure_time_absolute counts
100 us); every setting is read back and a camera that clamps it says so. A read waits at most
OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT seconds (2, set by the `drivers` package before cv2 loads; the
backend ignores CAP_PROP_READ_TIMEOUT_MSEC). Frames are numbered as they arrive and carry the driver's
buffer timestamp; a buffer whose timestamp does not advance is stale, a gap of more than 1.5
frame periods counts dropped frames.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any, Protocol

import cv2
import numpy as np

from drivers.base import Camera, Frame
from drivers.errors import (
    DeviceDisconnectedError,
    DeviceError,
    DeviceNotFoundError,
    DeviceProtocolError,
    DeviceTimeoutError,
)
from drivers.machine import access_problem
from drivers.options import DeviceConfig

V4L2_EXPOSURE_UNIT_US = 100.0
V4L2_MANUAL_EXPOSURE = 1  # V4L2_EXPOSURE_MANUAL, as OpenCV's V4L2 backend takes it


class VideoCaptureLike(Protocol):
    """The part of cv2.VideoCapture the driver uses."""

    def isOpened(self) -> bool: ...  # noqa: N802 - OpenCV's names

    def set(self, prop: int, value: float) -> bool: ...

    def get(self, prop: int) -> float: ...

    def grab(self) -> bool: ...

    def retrieve(self) -> tuple[bool, Any]: ...

    def release(self) -> None: ...


def _opencv_capture(device: str) -> VideoCaptureLike:
    return cv2.VideoCapture(device, cv2.CAP_V4L2)


class V4l2Camera(Camera):
    """A V4L2 camera at `device` (/dev/video0 or a /dev/v4l/by-id/ link)."""

    @classmethod
    def from_config(cls, device: DeviceConfig) -> V4l2Camera:
        """The camera a config's `v4l2` section and camera settings describe."""
        v = device.v4l2
        return cls(
            device.name,
            v.device,
            device.resolution,
            v.pixel_format,
            device.exposure_us,
            device.gain,
            v.buffer_frames,
            v.frame_period_s,
            mono=not device.color,
            max_exposure_us=v.max_exposure_us,
        )

    def __init__(
        self,
        name: str,
        device: str,
        resolution: tuple[int, int],
        pixel_format: str = "GREY",
        exposure_us: float = 10000.0,
        gain: float | None = None,
        buffer_frames: int = 2,
        frame_period_s: float = 1 / 30,
        capture_factory: Callable[[str], VideoCaptureLike] | None = None,
        mono: bool = True,
        max_exposure_us: float = 1_000_000.0,
    ) -> None:
        super().__init__(name)
        # exposure_time_absolute counts 100 us from 1; its maximum is the camera's own (v4l2-ctl -l)
        self.exposure_range_us = (V4L2_EXPOSURE_UNIT_US, max_exposure_us)
        if len(pixel_format) != 4:
            raise ValueError(f"{name}: pixel_format is a V4L2 fourcc such as GREY, YUYV or MJPG")
        self.device = device
        self._resolution = resolution
        self.pixel_format = pixel_format
        self._exposure_us = exposure_us
        self._gain = gain
        self.buffer_frames = buffer_frames
        self.frame_period_s = frame_period_s
        self._factory = capture_factory or _opencv_capture
        self.mono = mono
        self._cap: VideoCaptureLike | None = None
        self._sequence = 0
        self._last_stamp_ms: float | None = None
        self.dropped = 0

    @property
    def resolution(self) -> tuple[int, int]:
        return self._resolution

    def _set_checked(self, prop: int, value: float, what: str, tolerance: float = 0.5) -> None:
        assert self._cap is not None
        self._cap.set(prop, value)
        actual = self._cap.get(prop)
        if abs(actual - value) > tolerance:
            raise DeviceError(
                f"{self.name}: {what} {value:g} was not taken (the camera reports {actual:g}); "
                "it may be outside the camera's range"
            )

    def _do_set_exposure_us(self, exposure_us: float) -> None:
        self._set_checked(cv2.CAP_PROP_EXPOSURE, round(exposure_us / V4L2_EXPOSURE_UNIT_US), "exposure (100 us)")

    has_gain = True  # V4L2_CID_GAIN; a camera without it refuses the value (_set_checked)
    has_exposure = True

    def _do_set_gain(self, gain: float) -> None:
        self._set_checked(cv2.CAP_PROP_GAIN, gain, "gain")

    def _do_open(self) -> None:
        if self.device.startswith("/dev/") and not os.path.exists(self.device):
            raise DeviceNotFoundError(f"{self.name}: {self.device} does not exist (see `slrig devices`)")
        cap = self._factory(self.device)
        if not cap.isOpened():
            cap.release()
            raise DeviceNotFoundError(
                f"{self.name}: cannot open {self.device} (in use, or no permission: "
                "is the service user in the video group?)"
            )
        self._cap = cap
        try:
            cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*self.pixel_format))
            width, height = self._resolution
            self._set_checked(cv2.CAP_PROP_FRAME_WIDTH, width, "width")
            self._set_checked(cv2.CAP_PROP_FRAME_HEIGHT, height, "height")
            cap.set(cv2.CAP_PROP_BUFFERSIZE, self.buffer_frames)
            self._set_checked(cv2.CAP_PROP_AUTO_EXPOSURE, V4L2_MANUAL_EXPOSURE, "manual exposure mode")
            self._do_set_exposure_us(self._exposure_us)
            if self._gain is not None:
                self._do_set_gain(self._gain)
        except Exception:
            cap.release()
            self._cap = None
            raise
        self._sequence = 0
        self._last_stamp_ms = None

    def _do_close(self) -> None:
        if self._cap is not None:
            self._cap.release()
        self._cap = None

    def _grab(self, deadline: float) -> float:
        """Grab the next buffer before `deadline`; returns its timestamp (ms)."""
        assert self._cap is not None
        if time.monotonic() > deadline:
            raise DeviceTimeoutError(f"{self.name}: no frame within the capture timeout")
        if not self._cap.grab():  # bounded by OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT
            if self.device.startswith("/dev/") and not os.path.exists(self.device):
                raise DeviceDisconnectedError(f"{self.name}: {self.device} is gone (unplugged?)")
            raise DeviceTimeoutError(f"{self.name}: no frame within the capture timeout")
        return float(self._cap.get(cv2.CAP_PROP_POS_MSEC))

    def _do_flush(self) -> None:
        deadline = time.monotonic() + (self.buffer_frames + 2) * self.frame_period_s + 1.0
        for _ in range(self.buffer_frames):
            self._last_stamp_ms = self._grab(deadline)
            self._sequence += 1

    def _do_capture(self, deadline: float) -> Frame:
        assert self._cap is not None
        stamp = self._grab(deadline)
        if self._last_stamp_ms is not None:
            if stamp <= self._last_stamp_ms:
                raise DeviceProtocolError(f"{self.name}: stale frame (timestamp {stamp:.1f} ms did not advance)")
            gap = (stamp - self._last_stamp_ms) / 1000.0
            if gap > 1.5 * self.frame_period_s:
                self.dropped += round(gap / self.frame_period_s) - 1
        self._last_stamp_ms = stamp
        ok, image = self._cap.retrieve()
        if not ok or image is None:
            raise DeviceProtocolError(f"{self.name}: the driver delivered no image for a grabbed frame")
        if self.mono and image.ndim == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        height, width = image.shape[:2]
        if (width, height) != self._resolution:
            raise DeviceProtocolError(
                f"{self.name}: frame is {width}x{height}, expected {self._resolution[0]}x{self._resolution[1]}"
            )
        self._sequence += 1
        bit_depth = 8 if image.dtype == np.uint8 else 16
        return Frame(
            image=image,
            timestamp_s=stamp / 1000.0,
            sequence=self._sequence,
            exposure_us=self._exposure_us,
            gain=self._gain or 0.0,
            bit_depth=bit_depth,
            meta={"dropped_before": self.dropped},
        )


def machine_problems(device: DeviceConfig) -> list[str]:
    """The video node, and the service user's access to it (slrig doctor)."""
    problem = access_problem(device.v4l2.device, "video") if device.v4l2 is not None else None
    return [problem] if problem else []
