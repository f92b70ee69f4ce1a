"""Accuracy of a simulated scan against the bench's ground truth."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from drivers.sim import GroundTruth
from rig.scan import PairResult

# Within this distance of the pixel's own true point the surface is treated as its tangent plane;
# farther points are measured to the nearest true surface sample instead.
_LOCAL_MM = 2.0
COMPLETE_WITHIN_MM = 1.0


def surface_distances(grid: np.ndarray, valid: np.ndarray, truth: GroundTruth) -> np.ndarray:
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
    local = has_truth & (np.linalg.norm(np.nan_to_num(offset, nan=np.inf), axis=1) <= _LOCAL_MM)
    dist = np.empty(len(idx))
    dist[local] = np.abs(np.einsum("ij,ij->i", offset[local], normal[local]))
    far = ~local
    if far.any():
        samples = truth.points.reshape(-1, 3)[truth.hit.ravel()]
        dist[far], _ = cKDTree(samples).query(rec[far])
    return dist


def evaluate_pair(pair: PairResult, truth: GroundTruth) -> dict[str, float | int]:
    """rms/mean/p95 distance to the true surface, and completeness: the fraction of camera pixels
    that see a lit, unshadowed true surface and got a point within 1 mm of it."""
    valid = np.isfinite(pair.grid).all(axis=2)
    dist = surface_distances(pair.grid, valid, truth)
    target = truth.hit & truth.lit
    good = np.zeros(valid.size, dtype=bool)
    good[np.flatnonzero(valid.ravel())] = dist <= COMPLETE_WITHIN_MM
    covered = good.reshape(valid.shape) & target
    n = max(1, len(dist))
    return {
        "points": int(valid.sum()),
        "rms_mm": float(np.sqrt(np.mean(dist**2))) if len(dist) else float("nan"),
        "mean_abs_mm": float(np.mean(dist)) if len(dist) else float("nan"),
        "p95_mm": float(np.percentile(dist, 95)) if len(dist) else float("nan"),
        "max_mm": float(np.max(dist)) if len(dist) else float("nan"),
        "outliers_over_5mm": int((dist > 5.0).sum()),
        "outlier_fraction": float((dist > 5.0).sum() / n),
        "completeness": float(covered.sum() / max(1, target.sum())),
        "target_pixels": int(target.sum()),
    }
