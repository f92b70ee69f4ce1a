"""How far the surface between the rings can be from the object, from the scan alone (no truth):
the surface rebuilt from every other ring, measured at the rings it left out.

Every ring sample is a measured point of the object, but the surface passes through all of them,
so they cannot judge it. Leave out the odd rings, interpolate the even ones exactly as the scan
did (the same interpolant, holes and fill, each pixel's annulus read against the even rings only),
and the odd rings' samples lie where the surface of twice the spacing should pass: their distance
to it (along each sample's normal) is that surface's error, at the places between rings where an
interpolant errs most. An interpolant's error grows with the spacing, so this bounds, from above,
the error of the surface at the scan's own spacing. As the promise is, it is judged region by
region (the scan's surface split at depth steps, rig.evaluate.regions): the worst region's p95.
"""

from __future__ import annotations

import numpy as np

from rig.evaluate.regions import MIN_REGION_SHARE, STEP_MM, footprints
from rig.geometry import CameraModel
from rig.opened_rig import Rig
from rig.pipeline import (
    Interpolant,
    PairResult,
    RingBands,
    RingSurface,
    SurfaceSettings,
    interpolate_surface,
    ring_bands,
    ring_lit,
)

_MIN_SAMPLES = 50  # fewer left-out samples in a region: no verdict on it


def held_out_error(rig: Rig, pair: PairResult) -> float | None:
    """A ring pair's surface judged by its own rings: the worst region's p95 (mm) of the odd rings'
    distance to the surface of the even rings alone; None without a surface or enough samples."""
    if pair.surface is None or pair.rings is None:
        return None
    config, corr = rig.config.scan.surface, pair.correspondence
    pixel, distances = held_out_distances(
        pair.surface,
        pair.rings.camera_xy[pair.rings.kept],
        rig.camera_models[pair.camera],
        rig.projector_models[pair.projector],
        ring_lit(rig, corr),
        config.interpolant,
        SurfaceSettings(max_gap_px=config.max_gap_px),
        ring_bands(corr),
    )
    area, region = footprints(pair.surface.grid.astype(np.float32, copy=False), pair.surface.valid, STEP_MM)
    label = np.full(pair.surface.valid.size, -1)
    label[np.flatnonzero(pair.surface.valid.ravel())] = region
    per_region = np.bincount(region, weights=area)
    worst = None
    for r in np.flatnonzero(per_region >= MIN_REGION_SHARE * per_region.sum()):
        here = distances[label[pixel] == r]
        if len(here) >= _MIN_SAMPLES:
            worst = max(worst or 0.0, float(np.percentile(here, 95)))
    return worst


def held_out_distances(
    surface: RingSurface,
    xy: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    lit: np.ndarray | None,
    method: Interpolant,
    settings: SurfaceSettings,
    bands: RingBands | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The flat camera pixel of each odd ring's sample the surface of the even rings alone covers,
    and the sample's distance (mm) to it; `surface` is the scan's own (its samples, normals and
    rings) and `xy` the samples' sub-pixel camera positions."""
    ring = surface.ring
    even = ring % 2 == 0
    half_bands = None
    if bands is not None:  # annulus a lay between rings a-1 and a; among the even rings, (a + 1) // 2
        annulus = np.where(bands.annulus >= 0, (bands.annulus.astype(np.int32) + 1) // 2, -1).astype(np.int16)
        half_bands = RingBands(annulus, bands.angle, bands.radii_px[::2], bands.center_px)
    coarse = interpolate_surface(
        surface.vertices[even], xy[even], ring[even] // 2, camera, projector, lit, method, settings, half_bands
    )
    odd = np.flatnonzero(~even)
    col = np.clip(np.rint(xy[odd, 0]).astype(np.int64), 0, camera.width - 1)
    row = np.clip(np.rint(xy[odd, 1]).astype(np.int64), 0, camera.height - 1)
    seen = coarse.valid[row, col]
    offset = surface.vertices[odd[seen]] - coarse.grid[row[seen], col[seen]]
    pixel = row[seen] * camera.width + col[seen]
    return pixel, np.abs(np.einsum("ij,ij->i", offset, surface.normals[odd[seen]]))
