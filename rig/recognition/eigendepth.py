"""The eigen-depth baseline: a plain PCA over depth maps (eigenfaces on range images), to compare
the ring descriptor with.

A scan's depth map is its surface resampled on a square grid across an axis, about a reference
point (the descriptor's own, so both start from the same alignment), as heights below that point
within a disc; cells the scan did not see take the lowest height seen. PCA is fitted to the
gallery's maps; a map is compared in the PCA space by the cosine of its whitened coefficients (the
"Mahalanobis cosine", the usual best metric for eigenfaces). Unlike the ring descriptor's
spectrum, a depth map turns with the object about the axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.errors import RecognitionError
from rig.recognition.geodesic import fill_holes, height_field

CELL_MM = 2.0


def depth_map(points: np.ndarray, reference: np.ndarray, axis: np.ndarray, radius_mm: float) -> np.ndarray:
    """(D,) the heights below `reference` along `axis` on the cells of a disc of `radius_mm`."""
    field = fill_holes(height_field(points, reference, axis, radius_mm, CELL_MM))
    top = float((reference - field.origin) @ field.axes[2])
    rows, cols = field.height.shape
    v, u = np.mgrid[0:rows, 0:cols] - (rows - 1) / 2.0
    disc = np.hypot(u, v) * CELL_MM <= radius_mm
    heights = field.height[disc] - top
    seen = np.isfinite(heights)
    if seen.mean() < 0.5:
        raise RecognitionError(
            f"too little surface for a depth map: {seen.mean():.0%} of the disc within {radius_mm:g} mm"
        )
    return np.where(seen, heights, heights[seen].min())


@dataclass(frozen=True, eq=False)
class EigenDepth:
    """PCA of depth maps: the mean map, the principal directions and their spreads."""

    mean: np.ndarray  # (D,)
    basis: np.ndarray  # (C, D) orthonormal rows
    spread: np.ndarray  # (C,) standard deviation of the maps along each row

    @classmethod
    def fit(cls, maps: np.ndarray, energy: float = 0.99) -> EigenDepth:
        """The fewest components holding `energy` of the maps' variance (at most one fewer than maps)."""
        if len(maps) < 2:
            raise RecognitionError("eigen-depth needs at least two depth maps to fit")
        mean = maps.mean(axis=0)
        _, singular, rows = np.linalg.svd(maps - mean, full_matrices=False)
        variance = singular**2 / (len(maps) - 1)
        kept = variance > 1e-12 * variance[0]
        held = np.cumsum(variance[kept]) / variance[kept].sum()
        count = int(np.searchsorted(held, energy) + 1)
        return cls(mean, rows[:count], np.sqrt(variance[:count]))

    def coefficients(self, maps: np.ndarray) -> np.ndarray:
        """(N, C) whitened coordinates of maps (N, D) in the PCA space."""
        return (np.atleast_2d(maps) - self.mean) @ self.basis.T / self.spread

    def similarity(self, probes: np.ndarray, gallery: np.ndarray) -> np.ndarray:
        """(P, G) the cosine of the whitened coefficients of each probe map with each gallery map."""
        a, b = self.coefficients(probes), self.coefficients(gallery)
        a = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)
        b = b / np.maximum(np.linalg.norm(b, axis=1, keepdims=True), 1e-300)
        return a @ b.T
