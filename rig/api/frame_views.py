"""A camera frame as the console shows it: a JPEG (downscaled to a requested width, optionally with
saturated pixels red and too-dark ones blue) and its figures (histogram, clipped fractions, focus).

Each (frame, width, overlay) is encoded once, whoever asks: four viewers cost one encoding.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import cv2
import numpy as np

from rig.patterns import sharpness
from rig.service import TappedFrame

HISTOGRAM_BINS = 64
DARK_FRACTION = 0.02  # at or below 2 % of full scale: too dark to decode
JPEG_QUALITY = 85


@dataclass(frozen=True)
class FrameView:
    jpeg: bytes
    headers: dict[str, str]


def frame_view(tapped: TappedFrame, width: int | None, overlay: bool, figures: bool = True) -> FrameView:
    """`figures`: the histogram and focus figure too (left out while a job runs: nobody focuses
    while patterns flash, and they are most of a view's cost)."""
    frame = tapped.frame
    full = frame.full_scale
    image = frame.image
    mono = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    saturated = (image >= full).any(axis=2) if image.ndim == 3 else image >= full
    dark = mono <= full * DARK_FRACTION
    pixels = float(mono.size)
    clipped = (np.count_nonzero(saturated) / pixels, np.count_nonzero(dark) / pixels)
    display = image if full == 255 else (image.astype(np.float32) * (255.0 / full)).astype(np.uint8)
    height, full_width = mono.shape
    if width is not None and width < full_width:
        size = (width, max(1, round(height * width / full_width)))
        display = cv2.resize(display, size, interpolation=cv2.INTER_AREA)
        saturated = cv2.resize(saturated.view(np.uint8), size, interpolation=cv2.INTER_AREA) > 0
        dark = cv2.resize(dark.view(np.uint8), size, interpolation=cv2.INTER_AREA) > 0
    if overlay:
        display = cv2.cvtColor(display, cv2.COLOR_GRAY2BGR) if display.ndim == 2 else display.copy()
        display[dark] = (255, 0, 0)  # BGR: blue
        display[saturated] = (0, 0, 255)  # red
    ok, encoded = cv2.imencode(".jpg", display, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise RuntimeError("JPEG encoding failed")
    headers = {
        "X-Frame": str(tapped.count),
        "X-Camera-Sequence": str(frame.sequence),
        "X-Exposure-Us": f"{frame.exposure_us:g}",
        "X-Gain": f"{frame.gain:g}",
        "X-Bit-Depth": str(frame.bit_depth),
        "X-Saturated-Fraction": f"{clipped[0]:.6f}",
        "X-Dark-Fraction": f"{clipped[1]:.6f}",
        "Cache-Control": "no-store",
    }
    if figures:
        headers["X-Sharpness"] = f"{sharpness(mono, full):.2f}"
        headers["X-Histogram"] = ",".join(str(int(c)) for c in histogram(mono, frame.bit_depth))
    return FrameView(encoded.tobytes(), headers)


def histogram(mono: np.ndarray, bit_depth: int) -> np.ndarray:
    """HISTOGRAM_BINS equal bins over the full scale (2**bit_depth counts: a shift, not a division)."""
    shift = max(0, bit_depth - 6)  # 64 bins
    return np.bincount((mono >> shift).ravel(), minlength=1 << min(bit_depth, 6))[:HISTOGRAM_BINS]


class FrameViews:
    """The encoded views of each camera's newest frame, kept until a newer frame comes."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._views: dict[tuple[int, int, int | None, bool, bool], FrameView] = {}
        self._encoded: dict[int, float] = {}  # camera: when its last view was made (time.monotonic)
        self._making: dict[int, threading.Lock] = {}

    def last_encoded(self, camera: int) -> float:
        with self._lock:
            return self._encoded.get(camera, 0.0)

    def view(self, camera: int, tapped: TappedFrame, width: int | None, overlay: bool, figures: bool) -> FrameView:
        key = (camera, tapped.count, width, overlay, figures)
        with self._lock:
            making = self._making.setdefault(camera, threading.Lock())
        with making:  # one encoding per camera at a time: viewers asking together wait for it, then share it
            with self._lock:
                found = self._views.get(key)
            if found is not None:
                return found
            made = frame_view(tapped, width, overlay, figures)
            with self._lock:
                self._encoded[camera] = time.monotonic()
                stale = [k for k in self._views if k[0] == camera and k[1] < tapped.count]
                for k in stale:
                    del self._views[k]
                self._views[key] = made
            return made
