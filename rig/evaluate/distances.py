"""Distances of reconstructed points to the bench's true surface."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from rig.rig import PixelTruth

# Within this distance of the pixel's own true point the surface is treated as its tangent plane;
# farther points are measured to the nearest true surface sample instead.
LOCAL_MM = 2.0


def surface_distances(grid: np.ndarray, valid: np.ndarray, truth: PixelTruth) -> np.ndarray:
    """Distance (mm) of each valid reconstructed point (H, W, 3) to the true surface, per valid pixel.

    A point near its pixel's true point is measured along the true normal (exact for planes, and
    for smooth surfaces to second order); a far one (an outlier) to the nearest true sample point
    seen by the camera, which overestimates by at most the sample spacing.
    """
    idx = np.flatnonzero(valid.ravel())
    rec = grid.reshape(-1, 3)[idx]
    true = truth.points.reshape(-1, 3)[idx]
    normal = truth.normals.reshape(-1, 3)[idx]
    offset = rec - true
    has_truth = truth.hit.ravel()[idx]
    local = has_truth & (np.linalg.norm(np.nan_to_num(offset, nan=np.inf), axis=1) <= LOCAL_MM)
    dist = np.empty(len(idx))
    dist[local] = np.abs(np.einsum("ij,ij->i", offset[local], normal[local]))
    far = ~local
    if far.any():
        samples = truth.points.reshape(-1, 3)[truth.hit.ravel()]
        dist[far], _ = cKDTree(samples).query(rec[far])
    return dist
