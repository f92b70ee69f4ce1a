"""Accuracy of the surface interpolated between the rings, against the bench's truth."""

from __future__ import annotations

import numpy as np

from rig.config import RigConfig
from rig.evaluate.distances import root_mean_square, surface_distances
from rig.patterns import codec_class
from rig.pipeline.scan import PairResult, ScanResult
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
        "surface_rms_mm": None if empty else root_mean_square(dist),
        "surface_p95_mm": None if empty else float(np.percentile(dist, 95)),
        "surface_max_mm": None if empty else float(np.max(dist)),
        "surface_over_1mm_fraction": float((dist > 1.0).sum() / max(1, len(dist))),
        "surface_completeness": float((close.reshape(valid.shape) & target).sum() / max(1, target.sum())),
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
