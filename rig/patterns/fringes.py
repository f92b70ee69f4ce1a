"""N-step phase shifting shared by the fringe codecs: pattern images and the sums that decode them."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from rig.patterns.correspondence import NormalizedFrames, fraction
from rig.workers import point_blocks

PATTERN_ROWS = 64  # rows of a pattern made at once: float temporaries of a band, not of the image


def fringe_images(phase: np.ndarray, steps: int) -> Iterator[np.ndarray]:
    """0.5 + 0.5 cos(phase - 2 pi n / steps) for n < steps, as uint8 images, one at a time as they
    are asked for (each made a band of rows at a time)."""
    for n in range(steps):
        image = np.empty(phase.shape, np.uint8)
        for rows in point_blocks(len(phase), PATTERN_ROWS):
            image[rows] = np.rint((0.5 + 0.5 * np.cos(phase[rows] - 2 * np.pi * n / steps)) * 255)
        yield image


def phase_sums(frames: NormalizedFrames, first: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """S = sum I_n sin(d_n) and C = sum I_n cos(d_n) of `steps` frames from index `first`
    (d_n = 2 pi n / steps): the phase is atan2(S, C), the modulation (2 / steps) |(S, C)|."""
    sums = summed(frames, first, steps)
    return sums.s, sums.c


def summed(frames: NormalizedFrames, first: int, steps: int) -> RunningSums:
    """`steps` frames from index `first` added into running sums, all at once."""
    sums = RunningSums(steps)
    for n in range(steps):
        sums.add(frames[first + n])
    return sums


class RunningSums:
    """phase_sums one step at a time, as the frames arrive (the same sums in the same order)."""

    def __init__(self, steps: int) -> None:
        self.steps = steps
        self.added = 0
        self._s: np.ndarray | None = None
        self._c: np.ndarray | None = None

    def add(self, values: np.ndarray) -> None:
        """The next step, in fractions of full scale (float32): a frame, or its values at some pixels."""
        if self.added >= self.steps:
            raise ValueError(f"{self.steps} steps already added")
        if self._s is None or self._c is None:
            self._s, self._c = np.zeros(values.shape, np.float32), np.zeros(values.shape, np.float32)
        delta = 2 * np.pi * self.added / self.steps
        self._s += values * np.float32(math.sin(delta))
        self._c += values * np.float32(math.cos(delta))
        self.added += 1

    @property
    def done(self) -> bool:
        return self.added == self.steps

    @property
    def s(self) -> np.ndarray:
        assert self._s is not None, "no step added"
        return self._s

    @property
    def c(self) -> np.ndarray:
        assert self._c is not None, "no step added"
        return self._c


class PointSums(RunningSums):
    """Running sums at a few pixels only: the ring codec's fine angle is needed at its ring points
    alone, which are known before its frames arrive."""

    def __init__(self, pixels: tuple[np.ndarray, np.ndarray], steps: int) -> None:
        super().__init__(steps)
        self.pixels = pixels

    def values_in(self, counts: np.ndarray, full_scale: int) -> np.ndarray:
        """An integer frame's values at `pixels` in fractions of full scale, as NormalizedFrames
        converts them."""
        return fraction(counts[self.pixels], full_scale)

    def at_ends(self) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """S and C, each split into its first and second half of the pixels (a crossing's two ends)."""
        half = len(self.pixels[0]) // 2
        return (self.s[:half], self.s[half:]), (self.c[:half], self.c[half:])
