"""Frames deconvolved by the camera's optical blur before they are decoded. The lens spreads each
point's light over its neighbours; beside a far brighter neighbour (a black part on white paper) a
pixel then reads more of the neighbour's pattern than its own, and its code lies toward the
neighbour. The projector's blur does not do this (it blurs the pattern before the surface's albedo
multiplies it), the camera's does, and a known Gaussian blur of sigma s is undone, to the frequencies
noise allows, by Van Cittert's iteration f <- f + (g - G_s * f), g the frame as captured: more
iterations for more blur (20 s^2, at least 4), which recover more of the edge with little ringing
(a regularised inverse filter rang at a 10:1 edge as much as the dark side's own light). A blur
of 0.6 px takes a dark pixel's error beside a white one from 0.62 to 0.34 px at most, 0.040 to
0.007 px on average (tests/test_deblur.py's checker); beyond about 0.9 px the iteration no longer
converges in reasonable time, and the setting stops there.

A pixel within reach of a clipped one is set to full scale: clipping broke the linearity the
deconvolution relies on, and the codecs leave saturated pixels out (rig.patterns.saturation)."""

from __future__ import annotations

import math

import cv2
import numpy as np

from rig.patterns.spill import SPILL_RATIO

ITERATIONS_PER_SIGMA2 = 20  # Van Cittert's iterations for a blur of sigma px: this times sigma^2


class Deblur:
    """The frames of one camera, each restored as it arrives where the first (the white frame)
    shows a strong edge in brightness; elsewhere a frame is left as captured (deconvolution adds
    noise, and only beside such an edge is there a neighbour's light to take back)."""

    def __init__(self, sigma_px: float, full_scale: int) -> None:
        self.sigma_px, self.full_scale = sigma_px, full_scale
        self.iterations = max(4, math.ceil(ITERATIONS_PER_SIGMA2 * sigma_px**2))
        reach = 2 * math.ceil(2 * sigma_px) + 1
        self._reach = cv2.getStructuringElement(cv2.MORPH_RECT, (reach, reach))
        self._zone: np.ndarray | None = None

    def restored(self, frame: np.ndarray) -> np.ndarray:
        """The frame deconvolved near strong edges, in its own sample type and scale."""
        if self._zone is None:
            self._zone = self._edges(frame)
        if not self._zone.any():
            return frame
        estimate = self._inverse(frame.astype(np.float32))
        clipped = frame >= self.full_scale
        if clipped.any():
            estimate[cv2.dilate(clipped.astype(np.uint8), self._reach) > 0] = self.full_scale
        np.clip(estimate, 0, self.full_scale, out=estimate)
        return np.where(self._zone, np.rint(estimate).astype(frame.dtype), frame)

    def _inverse(self, captured: np.ndarray) -> np.ndarray:
        estimate = captured.copy()
        for _ in range(self.iterations):
            estimate += captured - cv2.GaussianBlur(estimate, (0, 0), self.sigma_px, borderType=cv2.BORDER_REFLECT)
        return estimate

    def _edges(self, white: np.ndarray) -> np.ndarray:
        """Pixels within the blur's reach of an edge whose bright side is SPILL_RATIO times its dark one."""
        grey = white.astype(np.float32)
        if grey.ndim == 3:
            grey = grey.mean(axis=2)
        brightest, darkest = cv2.dilate(grey, self._reach), cv2.erode(grey, self._reach)
        zone = brightest > SPILL_RATIO * np.maximum(darkest, np.float32(1.0))
        return zone[..., None] if white.ndim == 3 else zone
