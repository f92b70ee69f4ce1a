"""Accuracy of the surface interpolated between the rings, against the bench's truth."""

from __future__ import annotations

import numpy as np

from rig.evaluate.distances import surface_distances
from rig.pipeline.scan import PairResult
from rig.rig import PixelTruth

COMPLETE_WITHIN_MM = 1.0


def surface_metrics(pair: PairResult, truth: PixelTruth) -> dict[str, float | int | None]:
    """rms, p95 and max distance of the interpolated surface (one point per covered pixel) to the
    true surface, and its completeness: the fraction of pixels that see a lit true surface which the
    interpolated surface covers within 1 mm."""
    assert pair.surface is not None
    valid = pair.surface.valid
    dist = surface_distances(pair.surface.grid, valid, truth)
    target = truth.hit & truth.lit
    close = np.zeros(valid.size, dtype=bool)
    close[np.flatnonzero(valid.ravel())[dist <= COMPLETE_WITHIN_MM]] = True
    empty = len(dist) == 0
    return {
        "surface_pixels": len(dist),
        "surface_rms_mm": None if empty else float(np.sqrt(np.mean(dist**2))),
        "surface_p95_mm": None if empty else float(np.percentile(dist, 95)),
        "surface_max_mm": None if empty else float(np.max(dist)),
        "surface_over_1mm_fraction": float((dist > 1.0).sum() / max(1, len(dist))),
        "surface_completeness": float((close.reshape(valid.shape) & target).sum() / max(1, target.sum())),
    }
