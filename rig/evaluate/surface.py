"""Accuracy of the surface interpolated between the rings, against the bench's truth."""

from __future__ import annotations

from typing import Any

import numpy as np

from rig.config import RigConfig
from rig.evaluate.distances import root_mean_square, surface_distances
from rig.evaluate.regions import STEP_MM, footprints, region_errors
from rig.evaluate.wholeness import object_error, true_areas, wholeness
from rig.patterns import codec_class
from rig.pipeline.scan import PairResult, ScanResult
from rig.rig import PixelTruth

COMPLETE_WITHIN_MM = 1.0
AREA_QUANTILE = 0.95


def surface_metrics(pair: PairResult, truth: PixelTruth) -> dict[str, Any]:
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
    by_area = {} if empty else area_metrics(pair.surface.grid, valid, dist)
    samples = pair.correspondence.samples
    whole = {}
    if not empty and samples is not None and samples.ring_radii_px is not None:
        areas = true_areas(truth)
        whole = object_error(valid, dist, truth, area=areas[0])
        whole.update(wholeness(valid, truth, samples.ring_radii_px, samples.center_px, areas))
    return {
        **by_area,
        **whole,
        "surface_pixels": len(dist),
        "surface_rms_mm": None if empty else root_mean_square(dist),
        "surface_p95_mm": None if empty else float(np.percentile(dist, 95)),
        "surface_max_mm": None if empty else float(np.max(dist)),
        "surface_over_1mm_fraction": float((dist > 1.0).sum() / max(1, len(dist))),
        "surface_completeness": float((close.reshape(valid.shape) & target).sum() / max(1, target.sum())),
    }


def area_metrics(grid: np.ndarray, valid: np.ndarray, dist: np.ndarray) -> dict[str, Any]:
    """The surface's error by area (rig.evaluate.regions): its area-weighted p95 over the whole view,
    and over each region a depth step bounds that holds MIN_REGION_SHARE of the area or more,
    largest first."""
    areas, labels = footprints(grid.astype(np.float32), valid, STEP_MM)  # float32: half the steps' memory
    whole, regions = region_errors(dist, areas, labels, AREA_QUANTILE)
    return {
        "surface_area_p95_mm": whole.quantile_mm,
        "surface_worst_region_p95_mm": max((r.quantile_mm for r in regions), default=whole.quantile_mm),
        "surface_regions": [r.as_dict() for r in regions],
    }


def pattern_economy(result: ScanResult, config: RigConfig, dense: str = "phase") -> dict[str, float | int]:
    """The scan's frames and bytes beside those a dense scan (`dense` codec, as configured) of the
    same rig would take: the dense figures are counted from its patterns and the cameras' formats."""
    frames = 0
    frame_bytes = 0
    for projector in config.projectors:
        count = codec_class(dense)(tuple(projector.resolution), getattr(config.scan, dense)).frame_count
        frames += count
        for camera in config.cameras:
            width, height = camera.resolution
            samples = width * height * (3 if camera.color else 1)
            frame_bytes += count * samples * (1 if camera.bit_depth <= 8 else 2)
    return {
        "frames": result.frames_projected,
        "bytes": result.bytes_captured,
        f"{dense}_frames": frames,
        f"{dense}_bytes": frame_bytes,
        "fraction_of_dense_bytes": round(result.bytes_captured / max(frame_bytes, 1), 4),
    }
