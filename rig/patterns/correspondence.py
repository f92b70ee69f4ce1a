"""What every decoder shares: the frames as it reads them (NormalizedFrames, luminance, fractions
of full scale) and what it gives (a Correspondence, with RingSamples for the sparse ring codecs).
Data and arithmetic only: the codecs (rig.patterns.base) and their streams (rig.patterns.stream)
both build on it, neither on the other's module for it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import overload

import cv2
import numpy as np


@dataclass(frozen=True, eq=False)
class RingSamples:
    """Sparse correspondences on projected rings: sub-pixel camera positions where a ring was
    found, with the ring's index and radius and the decoded projector polar angle there."""

    camera_xy: np.ndarray  # (M, 2) float64, pixel centres at integers
    ring: np.ndarray  # (M,) int
    radius_px: np.ndarray  # (M,) float64, the ring's radius in the projector image
    theta: np.ndarray  # (M,) float64, projector polar angle about the centre, radians
    contrast: np.ndarray  # (M,) float32, |pattern - inverse| step across the ring edge
    center_px: tuple[float, float]  # the rings' centre in the projector image
    ring_radii_px: np.ndarray | None = None  # (K,) every ring's radius by index, seen or not
    # How triangulation treats the samples (the codec's parameters):
    min_cos_beta: float = 0.3
    min_radius_px: float = 0.0
    radius_sigma_px: float = 0.05
    model: str = "cone"  # see rig.patterns.rings.RingsParams.model
    # The fine angular code (rings' tangential_period_px), None without it: its wrapped phase at
    # each sample (NaN where unreadable) and the periods per revolution in the sample's ring zone.
    fine_phase: np.ndarray | None = None
    fine_periods: np.ndarray | None = None
    tangential_sigma_px: float = 0.1
    shown_within_px: tuple[float, float, float, float] | None = None  # where a ring's edge is whole: u, v bounds

    def __len__(self) -> int:
        return len(self.ring)


@dataclass(frozen=True, eq=False)
class Correspondence:
    """What one camera saw of one projector, per camera pixel (arrays (H, W)).

    `u`, `v`: projector column and row (pixel centres at integers), NaN where not decoded; a codec
    that codes one direction leaves the other None. `extra` holds codec-specific coordinates
    (ring radius, angle, index). `quality` is the codec's confidence (modulation or contrast, in
    fractions of full scale). `texture` is the fully lit frame as captured. Sparse codecs give
    `samples` at sub-pixel camera positions instead of per-pixel coordinates.
    """

    valid: np.ndarray
    quality: np.ndarray
    texture: np.ndarray
    u: np.ndarray | None = None
    v: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    full_scale: int = 255  # of `texture`
    samples: RingSamples | None = None


class NormalizedFrames(Sequence[np.ndarray]):
    """Captured frames as float32 luminance in [0, 1], converted when read (not all at once, which
    would hold a float copy of every frame). Slicing gives another NormalizedFrames."""

    def __init__(self, frames: Sequence[np.ndarray], full_scale: int) -> None:
        self._frames = frames
        self._full_scale = full_scale

    def __len__(self) -> int:
        return len(self._frames)

    @overload
    def __getitem__(self, index: int) -> np.ndarray: ...

    @overload
    def __getitem__(self, index: slice) -> NormalizedFrames: ...

    def __getitem__(self, index: int | slice) -> np.ndarray | NormalizedFrames:
        if isinstance(index, slice):
            return NormalizedFrames(self._frames[index], self._full_scale)
        return fraction(luminance(self._frames[index]), self._full_scale)

    def difference(self, first: int, second: int) -> np.ndarray:
        """Frame `first` less frame `second` in fractions of full scale, from their integer
        difference (as the streaming decoders compute it, so both read the same bits)."""
        first_counts = luminance(self._frames[first]).astype(np.int32)
        return fraction(first_counts - luminance(self._frames[second]), self._full_scale)


def luminance(frame: np.ndarray) -> np.ndarray:
    """A captured frame as one channel (colour frames are BGR), in its own integer type."""
    return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame


def fraction(counts: np.ndarray, full_scale: int) -> np.ndarray:
    """Integer counts (or differences of counts) as float32 fractions of full scale."""
    return counts.astype(np.float32) * np.float32(1.0 / full_scale)


def least_counts(threshold: float, full_scale: int) -> int:
    """The fewest integer counts whose `fraction` reaches `threshold` (full_scale + 1: none does), so
    that a decoder comparing counts keeps exactly the pixels one comparing fractions keeps."""
    reaches = fraction(np.arange(full_scale + 1), full_scale) >= threshold
    return int(np.argmax(reaches)) if reaches.any() else full_scale + 1
