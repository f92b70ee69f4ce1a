"""Accuracy of the surface interpolated between the rings, against the bench's truth."""

from __future__ import annotations

from typing import Any

import numpy as np

from rig.config import RigConfig
from rig.evaluate.distances import root_mean_square, surface_distances
from rig.evaluate.regions import region_errors
from rig.evaluate.wholeness import object_error, true_areas, wholeness
from rig.opened_rig import PixelTruth
from rig.patterns import codec_class
from rig.pipeline import PairResult, ScanResult

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
    close = np.zeros(valid.shape, dtype=bool)
    close[valid] = dist <= COMPLETE_WITHIN_MM  # dist is row-major over the valid pixels
    empty = len(dist) == 0
    areas = None if empty else true_areas(truth)
    by_area = {} if areas is None else area_metrics(valid, dist, areas)
    samples = pair.correspondence.samples
    whole = {}
    if areas is not None and samples is not None and samples.ring_radii_px is not None:
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
        "surface_completeness": float((close & target).sum() / max(1, target.sum())),
    }


def area_metrics(valid: np.ndarray, dist: np.ndarray, true: tuple[np.ndarray, np.ndarray]) -> dict[str, Any]:
    """The surface's error by area (rig.evaluate.regions): its area-weighted p95 over the whole view,
    and over each true region (a depth step or the support plane bounds it) that holds
    MIN_REGION_SHARE of the area or more, largest first. Each covered pixel weighs the true area it
    sees and counts in the true region it sees (`true`: true_areas), so a surface that runs on
    past an object's edge errs on the bench beyond it, not on the object."""
    area, region = true[0][valid], true[1][valid]
    # Surface where the truth sees nothing (spanning empty space) is judged too, as a region of its
    # own, each pixel weighing what a pixel typically sees.
    nowhere = region < 0
    if nowhere.any():  # in place: area and region are the valid pixels' copies
        area[nowhere] = float(np.median(area[~nowhere])) if (~nowhere).any() else 1.0
        region[nowhere] = region.max(initial=-1) + 1
    whole, regions = region_errors(dist, area, region, AREA_QUANTILE)
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
