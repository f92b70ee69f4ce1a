"""The simulated bench's ground truth per camera pixel, and the search for the nearest true point."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True, eq=False)
class PixelTruth:
    """Ground truth per camera pixel for one (camera, projector) pair; arrays are (H, W[, k])."""

    hit: np.ndarray  # a surface is seen
    points: np.ndarray  # world points, mm (NaN where no hit)
    normals: np.ndarray  # unit normals facing the camera
    depth: np.ndarray  # camera-frame z, mm (0 where no hit)
    projector_uv: np.ndarray  # projector pixel coordinates of the surface point
    lit: np.ndarray  # inside the projector's image, unshadowed and facing it
    albedo: np.ndarray  # (H, W, 3) float32 linear RGB of the surface seen (0 where no hit)
    white_irradiance: np.ndarray  # (H, W) float32: light on the surface under this projector's white frame
    seen: SeenSurface

    def nearest_distance(self, points: np.ndarray) -> np.ndarray:
        """(N,) distance (mm) of each point (N, 3) to the nearest true surface point the camera sees."""
        return self.seen.nearest_distance(points)


class SeenSurface:
    """The true points one camera sees (`points` (N, 3) of its pixels where `hit`), searched for the
    nearest. The search tree is built on the first query and kept with the camera's view, as its
    ray casts are: a scan's evaluation then costs no tree of its own (a 1.3 MP camera's is about
    60 MB), and a rig that never evaluates builds none."""

    def __init__(self, points: np.ndarray, hit: np.ndarray) -> None:
        self._points, self._hit = points, hit
        self._tree: cKDTree | None = None

    def nearest_distance(self, points: np.ndarray) -> np.ndarray:
        if len(points) == 0:
            return np.zeros(0)
        if self._tree is None:  # split at the midpoints, not the medians: built in half the time, the
            # same nearest points, queried as fast (1.3 M true points: 0.47-0.56 s against 0.24-0.32)
            self._tree = cKDTree(self._points[self._hit], balanced_tree=False)
        return self._tree.query(points)[0]
