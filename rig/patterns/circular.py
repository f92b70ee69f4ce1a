"""Shared parts of codecs whose patterns are circles about a centre in the projector image."""

from __future__ import annotations

import math

import numpy as np

from rig.patterns.base import Codec


def farthest_corner_px(width: int, height: int, center: tuple[float, float]) -> float:
    """Distance from `center` to the farthest corner pixel of a width x height image."""
    cu, cv = center
    return max(math.hypot(x - cu, y - cv) for x in (0, width - 1) for y in (0, height - 1))


class CircularCodec(Codec):
    """Patterns in polar coordinates (rho, theta) about `center` (params.center_px, or the image
    centre)."""

    @property
    def center(self) -> tuple[float, float]:
        center = getattr(self.params, "center_px", None)
        if center is not None:
            return center
        return ((self.width - 1) / 2, (self.height - 1) / 2)

    @property
    def reach(self) -> float:
        """Distance from the centre to the farthest image corner, pixels."""
        return farthest_corner_px(self.width, self.height, self.center)

    def radius(self) -> np.ndarray:
        """rho of every projector pixel (H, W): its distance from the centre."""
        u, v = self._offsets()
        return np.hypot(u, v)

    def angle(self) -> np.ndarray:
        """theta of every projector pixel (H, W): its polar angle about the centre."""
        u, v = self._offsets()
        return np.arctan2(v, u)

    def _offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """A row of the columns' and a column of the rows' offsets from the centre: broadcast, not
        image-sized index grids."""
        cu, cv = self.center
        v, u = np.ogrid[0 : self.height, 0 : self.width]
        return u - cu, v - cv
