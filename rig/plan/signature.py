"""What a plan's pilot looked like where the plan's rings fall on it: enough to tell, from a later
ring scan's own points and no truth, whether that scan sees the object the plan was made for.

Each ring is a cone of projector rays; where it meets the object, each ray's point lies some
distance from the projector. The signature keeps, per ring and per bin of polar angle, the median
of those distances on the pilot. A scan of the same object on the same rig finds its ring points at
the same distances (to within its noise) nearly everywhere; another object, or the same one moved,
does not where it stands.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rig.geometry import CameraModel
from rig.plan.rehearsal import PilotSurface, ring_samples

ANGLE_BINS = 72  # 5 degrees each
_MIN_SAMPLES = 3  # a bin with fewer ring points says nothing
_MIN_BINS = 8  # fewer shared bins: no verdict
_MIN_RING_BINS = 3  # a ring met in fewer bins is not judged alone


def pilot_signature(pilot: PilotSurface, radii: np.ndarray, center_px: tuple[float, float]) -> dict[str, Any]:
    """Per ring of `radii`, per polar-angle bin, the median distance (mm) of the pilot's points on
    that ring from the projector (None where the ring misses the pilot there)."""
    points, _, ring = ring_samples(pilot, np.asarray(radii, dtype=np.float64))
    table = binned_ranges(points, ring, len(radii), pilot.projector, center_px)
    return {
        "angle_bins": ANGLE_BINS,
        "range_mm": [[None if not np.isfinite(v) else round(float(v), 2) for v in row] for row in table],
    }


def binned_ranges(
    points: np.ndarray, ring: np.ndarray, rings: int, projector: CameraModel, center_px: tuple[float, float]
) -> np.ndarray:
    """(rings, ANGLE_BINS) median distance from the projector of the points of each ring in each
    bin of projector polar angle, NaN where fewer than a few points fall."""
    table = np.full((rings, ANGLE_BINS), np.nan)
    if len(points) == 0:
        return table
    uv, _ = projector.project(points)
    angle = np.arctan2(uv[:, 1] - center_px[1], uv[:, 0] - center_px[0])
    which = np.clip(((angle + np.pi) / (2 * np.pi) * ANGLE_BINS).astype(np.int64), 0, ANGLE_BINS - 1)
    distance = np.linalg.norm(points - projector.center, axis=1)
    cell = ring * ANGLE_BINS + which
    order = np.argsort(cell, kind="stable")
    cells, starts, counts = np.unique(cell[order], return_index=True, return_counts=True)
    for c, start, count in zip(cells, starts, counts, strict=True):
        if count >= _MIN_SAMPLES and 0 <= c < rings * ANGLE_BINS:
            table.flat[c] = np.median(distance[order[start : start + count]])
    return table


def disagreement(
    signature: dict[str, Any],
    points: np.ndarray,
    ring: np.ndarray,
    projector: CameraModel,
    center_px: tuple[float, float],
) -> float | None:
    """How far (mm) a scan's ring points lie from a pilot's signature: per ring, the median difference
    over the angle bins both have; of the rings, the worst (the bench the object stands on agrees
    whatever the object, and fills most bins: over all bins at once, an object on a few inner rings
    would be missed). None where too few bins are shared to say."""
    stored = np.array(
        [[np.nan if v is None else float(v) for v in row] for row in signature.get("range_mm", [])], dtype=np.float64
    )
    if stored.ndim != 2 or stored.shape[1] != ANGLE_BINS:
        return None
    found = binned_ranges(points, ring, stored.shape[0], projector, center_px)
    both = np.isfinite(found) & np.isfinite(stored)
    judged = both.sum(axis=1) >= _MIN_RING_BINS
    if both.sum() < _MIN_BINS or not judged.any():
        return None
    difference = np.where(both, np.abs(found - stored), np.nan)[judged]
    return float(np.nanmax(np.nanmedian(difference, axis=1)))
