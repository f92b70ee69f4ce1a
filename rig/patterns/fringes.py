"""N-step phase shifting shared by the fringe codecs: pattern images and the sums that decode them."""

from __future__ import annotations

import math

import numpy as np

from rig.patterns.base import NormalizedFrames


def fringe_images(phase: np.ndarray, steps: int) -> list[np.ndarray]:
    """0.5 + 0.5 cos(phase - 2 pi n / steps) for n < steps, as uint8 images."""
    return [np.rint((0.5 + 0.5 * np.cos(phase - 2 * np.pi * n / steps)) * 255).astype(np.uint8) for n in range(steps)]


def phase_sums(frames: NormalizedFrames, first: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """S = sum I_n sin(d_n) and C = sum I_n cos(d_n) of `steps` frames from index `first`
    (d_n = 2 pi n / steps): the phase is atan2(S, C), the modulation (2 / steps) |(S, C)|."""
    s = np.zeros(frames[first].shape, dtype=np.float32)
    c = np.zeros_like(s)
    for n in range(steps):
        delta = 2 * np.pi * n / steps
        frame = frames[first + n]
        s += frame * np.float32(math.sin(delta))
        c += frame * np.float32(math.cos(delta))
    return s, c
