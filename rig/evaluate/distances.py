"""Distances of reconstructed points to the bench's true surface."""

from __future__ import annotations

import numpy as np

from rig.opened_rig import PixelTruth
from rig.workers import point_blocks

# Within this distance of the pixel's own true point the surface is treated as its tangent plane;
# farther points are measured to the nearest true surface sample instead.
LOCAL_MM = 2.0


def surface_distances(grid: np.ndarray, valid: np.ndarray, truth: PixelTruth) -> np.ndarray:
    """Distance (mm) of each valid reconstructed point (H, W, 3) to the true surface, per valid pixel
    (pixel_distances)."""
    idx = np.flatnonzero(valid.ravel())
    return pixel_distances(grid.reshape(-1, 3), idx, truth, rows=idx)


def pixel_distances(
    points: np.ndarray, pixel: np.ndarray, truth: PixelTruth, rows: np.ndarray | None = None
) -> np.ndarray:
    """Distance (mm) to the true surface of each point `points[rows]` (all points without `rows`),
    seen at flat camera pixel `pixel`; float32, as the points (a scan's distances are read in
    micrometres, float32 carries seven digits).

    A point near its pixel's true point is measured along the true normal (exact for planes, and
    for smooth surfaces to second order); a far one (an outlier) to the nearest true sample point
    seen by the camera, which overestimates by at most the sample spacing.
    """
    true_points, true_normals = truth.points.reshape(-1, 3), truth.normals.reshape(-1, 3)
    has_truth = truth.hit.ravel()
    dist, far = np.empty(len(pixel), np.float32), np.zeros(len(pixel), bool)  # float32, as the points are
    for part in point_blocks(len(pixel)):  # a block at a time: no (N, 3) copies of the cloud
        at = pixel[part]
        offset = (points[part] if rows is None else points[rows[part]]) - true_points[at]
        local = has_truth[at] & (np.linalg.norm(np.nan_to_num(offset, nan=np.inf), axis=1) <= LOCAL_MM)
        dist[part][local] = np.abs(np.einsum("ij,ij->i", offset[local], true_normals[at][local]))
        far[part] = ~local
    if far.any():
        outliers = np.flatnonzero(far)
        dist[outliers] = truth.nearest_distance(points[outliers] if rows is None else points[rows[outliers]])
    return dist


def root_mean_square(values: np.ndarray) -> float:
    """sqrt(mean(values^2)) summed in float64 a block at a time: no squared copy of a cloud's
    length, and no float32 sum of a million terms. NaN for no values."""
    total = 0.0
    for part in point_blocks(len(values)):
        block = values[part].astype(np.float64)
        total += float(np.dot(block, block))
    return float(np.sqrt(total / len(values))) if len(values) else float("nan")
