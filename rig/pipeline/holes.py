"""Holes in the surface between the rings, from the scan alone: where the rings promise a surface
(lit pixels that read an annulus from the inner disc out to the outermost ring the pair found) and
the surface has none, joined into holes with their area.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from rig.geometry import CameraModel
from rig.pipeline.surface import RingBands, RingSurface

MIN_HOLE_PX = 20  # smaller gaps are a ring's width or a triangle's edge, not holes
LISTED = 10  # the largest holes listed one by one
_RIM_PX = 3  # the surface this near a hole gives its depth


def surface_holes(surface: RingSurface, bands: RingBands, lit: np.ndarray, camera: CameraModel) -> dict[str, Any]:
    """The holes of one pair's surface: how many, their total area (mm^2), and the largest few with
    their pixels, area and centre (camera px). A hole's area is its pixels times the footprint of a
    pixel at the depth of the surface around it (seen square-on: a hole on a slope is larger)."""
    found = surface.ring[np.bincount(surface.faces.ravel(), minlength=len(surface.ring)) > 0]
    if len(found) == 0:
        return {"holes": 0, "area_mm2": 0.0, "largest": []}
    promised = lit & (bands.annulus >= 0) & (bands.annulus <= int(found.max()))
    missing = (promised & ~surface.valid).astype(np.uint8)
    _, _, stats, centres = cv2.connectedComponentsWithStats(missing, connectivity=8)
    holes = []
    for label in np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= MIN_HOLE_PX) + 1:
        x, y, w, h = (int(v) for v in stats[label, :4])
        window = (slice(max(0, y - _RIM_PX), y + h + _RIM_PX), slice(max(0, x - _RIM_PX), x + w + _RIM_PX))
        around = camera.to_device(surface.grid[window][surface.valid[window]])[:, 2]  # the rim's depths alone
        if len(around) == 0:
            continue
        footprint = (float(np.median(around)) if camera.projection != "orthographic" else 1.0) / camera.K[0, 0]
        pixels = int(stats[label, cv2.CC_STAT_AREA])
        holes.append({"pixels": pixels, "area_mm2": round(pixels * footprint**2, 2),
                      "center_px": [round(float(c), 1) for c in centres[label]]})  # fmt: skip
    holes.sort(key=lambda h: -h["area_mm2"])
    return {
        "holes": len(holes),
        "area_mm2": round(sum(h["area_mm2"] for h in holes), 2),
        "largest": holes[:LISTED],
    }
