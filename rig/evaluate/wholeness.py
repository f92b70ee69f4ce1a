"""How whole a ring scan's surface is, against the bench's truth: the share of the area the rings
promise a surface at that the surface covers, the inner disc inside the innermost ring, and the
error on the object alone (the bench plane left out).

Each true surface is a region of the camera's view that a depth step or the support plane bounds
(rig.evaluate.regions, on the true points). The surface is promised between two rings the camera sees on it
(rig.evaluate.promise): a strip with a ring on one side only (beyond the last ring a limb lets the
camera see, up to a shadow's edge) is not, and is reported apart: the share of the lit object the
promise spans, and the share of it the surface covers.
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np

from rig.evaluate.promise import ProjectorRadius, between_rings, polar_rows
from rig.evaluate.regions import STEP_MM, footprints, weighted_quantile
from rig.opened_rig import PixelTruth

OBJECT_ABOVE_MM = 1.0  # the bench plane is z = 0 in the world: the object is what stands above it
CROWDED_PX = 12.0  # rings closer in the image are read poorly (8 to 12 px apart: a face's surface 1/3 covered)


# Each truth's areas, kept as long as the truth is: a bench keeps a pair's truth while its scene
# stands, and every scan of it is measured by the same areas (their making, 60 MB of temporaries
# on the default bench, was the peak of a scan's evaluation).
_AREAS: weakref.WeakKeyDictionary[PixelTruth, tuple[np.ndarray, np.ndarray]] = weakref.WeakKeyDictionary()


def true_areas(truth: PixelTruth) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) area (mm^2) of true surface each pixel sees (0 where none) and its region (-1 none),
    read-only: made once for each truth (kept as long as the truth is)."""
    try:
        return _AREAS[truth]
    except KeyError:
        pass
    except TypeError:  # a truth that cannot be referred to weakly: made each time
        return _true_areas(truth)
    areas = _true_areas(truth)
    for image in areas:
        image.flags.writeable = False  # shared by every scan measured against this truth
    _AREAS[truth] = areas
    return areas


def _true_areas(truth: PixelTruth) -> tuple[np.ndarray, np.ndarray]:
    # float32: a bench's points to a micrometre, and half the memory of the neighbours' steps
    areas, labels = footprints(truth.points.astype(np.float32), truth.hit, STEP_MM)
    area, region = np.zeros(truth.hit.shape), np.full(truth.hit.shape, -1, np.int32)  # int32: regions are few
    area[truth.hit], region[truth.hit] = areas, labels
    return area, region


# Each truth's promise, for the last few ring sets it was asked for: every scan of a standing scene
# by the same rings is promised the same pixels, and their making (image-sized labels, bands,
# sectors and pieces) was the peak of a ring scan's evaluation, some 20 MB above what the scan holds.
_PROMISES: weakref.WeakKeyDictionary[PixelTruth, dict[bytes, np.ndarray]] = weakref.WeakKeyDictionary()
_PROMISES_KEPT = 4  # ring sets per truth: an adaptive scan's plans come and go


def promised(
    truth: PixelTruth, radii: np.ndarray, center: tuple[float, float], areas: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """(H, W) read-only: the pixels the rings `radii` about `center` promise a surface at on the lit
    true surface (rig.evaluate.promise.between_rings; `areas`: true_areas(truth)), made once for
    each truth and ring set (kept as long as the truth is, for the last _PROMISES_KEPT ring sets)."""
    radii = np.asarray(radii, np.float64)
    key = radii.tobytes() + np.asarray(center, np.float64).tobytes()
    try:
        kept = _PROMISES.setdefault(truth, {})
    except TypeError:  # a truth that cannot be referred to weakly: made each time
        kept = {}
    if key in kept:
        target = kept[key] = kept.pop(key)  # to the back: the last asked for is kept longest
        return target
    area, region = areas
    target = between_rings(polar_rows(truth.projector_uv, center), region, area, truth.hit & truth.lit, radii)
    target.flags.writeable = False  # shared by every scan of this truth by these rings
    while len(kept) >= _PROMISES_KEPT:
        del kept[next(iter(kept))]  # the ring set asked for longest ago
    kept[key] = target
    return target


def wholeness(
    valid: np.ndarray,
    truth: PixelTruth,
    radii: np.ndarray,
    center: tuple[float, float],
    areas: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict[str, Any]:
    """Coverage (by area) of what the rings promise (rig.evaluate.promise.between_rings), over the
    whole view and on the object; the inner disc's; the share of the lit object promised and
    covered; and where the object's promised area went uncovered (surface_object_missed: inside the
    innermost ring, where neighbouring rings lie closer than CROWDED_PX camera pixels, elsewhere;
    shares of the promised area). `areas`: true_areas(truth), when already known."""
    areas = true_areas(truth) if areas is None else areas
    area, lit = areas[0], truth.hit & truth.lit
    target = promised(truth, radii, center, areas)
    radius = ProjectorRadius(truth.projector_uv, center)
    on_object = truth.points[..., 2] > OBJECT_ABOVE_MM
    inner = radius.within(radii[0])
    disc = lit & inner

    def share(mask: np.ndarray, of: np.ndarray | None = None) -> float | None:
        whole = float(area[mask].sum())
        return None if whole <= 0 else float(area[mask & (valid if of is None else of)].sum()) / whole

    return {
        "surface_coverage": share(target),
        "surface_object_coverage": share(target & on_object),
        "surface_inner_disc_coverage": share(disc),
        # beside the promise: how much of the lit object it spans, and how much the surface covers
        "surface_object_promised": share(lit & on_object, target),
        "surface_object_lit_coverage": share(lit & on_object),
        "surface_object_missed": _missed(
            target & on_object & ~valid, inner, area, radius, radii, float(area[target & on_object].sum())
        ),
    }


def _missed(
    missed: np.ndarray, inner: np.ndarray, area: np.ndarray, radius: ProjectorRadius, radii: np.ndarray, promised: float
) -> dict[str, float]:
    """Where the promised area went uncovered, as shares of it: the disc inside the innermost ring
    (`inner`), where the rings crowd closer than CROWDED_PX camera pixels (a flank turning away: the
    codec cannot read them), and elsewhere."""
    if promised <= 0:
        return {}
    disc = missed & inner
    crowded = np.zeros(missed.shape, bool)
    y, x = np.nonzero(missed & ~disc)  # the rings' spacing and the radius's slope at these pixels alone
    slope = np.hypot(_gradient(radius, y, x, 0), _gradient(radius, y, x, 1))
    at = np.nan_to_num(radius(y, x), nan=-1.0)
    band = np.clip(np.searchsorted(radii, at, side="right"), 1, max(1, len(radii) - 1))
    spacing = radii[np.minimum(band, len(radii) - 1)] - radii[band - 1]
    close = spacing < CROWDED_PX * slope
    crowded[y[close], x[close]] = True
    return {
        name: round(float(area[mask].sum()) / promised, 4)
        for name, mask in (("inner_disc", disc), ("crowded", crowded), ("elsewhere", missed & ~disc & ~crowded))
    }


def _gradient(image: ProjectorRadius, y: np.ndarray, x: np.ndarray, axis: int) -> np.ndarray:
    """np.gradient(np.nan_to_num(image))[axis] at the pixels (y, x) alone, of an image made at the
    pixels asked for (`image(y, x)`, its `shape`): central differences, one-sided at its edges."""
    at = [y, x]
    size = image.shape[axis]
    ahead, behind = at.copy(), at.copy()
    ahead[axis] = np.minimum(at[axis] + 1, size - 1)
    behind[axis] = np.maximum(at[axis] - 1, 0)
    step = (ahead[axis] - behind[axis]).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (np.nan_to_num(image(ahead[0], ahead[1])) - np.nan_to_num(image(behind[0], behind[1]))) / step


def object_error(
    grid_valid: np.ndarray, dist: np.ndarray, truth: PixelTruth, q: float = 0.95, area: np.ndarray | None = None
) -> dict[str, Any]:
    """The surface's error on the object alone (true points above the bench plane), weighted by the
    true area each pixel sees (`area`, true_areas' first, when already known): the quantile `q` and
    the rms; `dist` per valid pixel, row-major."""
    if area is None:
        area = true_areas(truth)[0]
    on_object = truth.points[..., 2] > OBJECT_ABOVE_MM
    on = on_object[grid_valid]
    weights = area[grid_valid & on_object]  # as area[grid_valid][on], without the valid pixels' copy
    if not on.any() or weights.sum() <= 0:
        return {"surface_object_p95_mm": None, "surface_object_rms_mm": None}
    d = dist[on].astype(np.float64)
    return {
        "surface_object_p95_mm": weighted_quantile(d, weights, q),
        "surface_object_rms_mm": float(np.sqrt(np.sum(weights * d**2) / weights.sum())),
    }
