"""Errors of a surface by its area, region by region: what a tolerance promises on the object.

A surface measured per point or per pixel gives a flat background, which most pixels see, the
weight of the object on it, and a steep object side, which few pixels see, almost none. Here each
covered pixel of a camera grid counts the area of the surface it stands for (its footprint), and
the surface is split into connected regions wherever neighbouring pixels' points jump apart (a
depth step), and apart from the plane it stands on (the bench or turntable, which an object joins
without a step wherever it touches it: a saddle's edges, a lying cylinder), so that an object and
the bench it stands on are judged each on its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.lazy import lazy_module

region_kernels = lazy_module("rig.kernels.regions")  # numba compiles on first use

STEP_MM = 2.0  # neighbouring points this far apart lie on two sides of a depth step
MIN_REGION_SHARE = 0.01  # regions smaller than this share of the area are not judged on their own
SUPPORT_SHARE = 0.2  # a plane holding this share of the view's pixels is what the object stands on
SUPPORT_SPACINGS = 3.0  # a pixel within this many pixel spacings of that plane lies on it
_SUPPORT_SAMPLE, _SUPPORT_TRIALS = 4000, 256
_BLOCK_ROWS = 1 << 16  # points taken at a time for their distance to the plane


def pixel_areas(grid: np.ndarray, valid: np.ndarray, max_jump_mm: float) -> np.ndarray:
    """The area (mm^2) of surface each valid pixel of `grid` (H, W, 3) stands for, from the cross
    product of its steps to the neighbouring pixels' points (central where both exist, one-sided at
    an edge or a depth step over `max_jump_mm`, which is no part of either surface); a pixel with no
    such neighbour along a direction takes its other direction's step."""
    return footprints(grid, valid, max_jump_mm, split_support=False)[0]


def surface_regions(grid: np.ndarray, valid: np.ndarray, max_jump_mm: float, split_support: bool = True) -> np.ndarray:
    """A region label per valid pixel: pixels joined through 4-neighbours whose points lie within
    `max_jump_mm` of each other, so a depth step separates the surfaces on its two sides, and (with
    `split_support`) both on or both off the support plane (support_plane)."""
    return footprints(grid, valid, max_jump_mm, split_support)[1]


def footprints(
    grid: np.ndarray, valid: np.ndarray, max_jump_mm: float | np.ndarray, split_support: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """pixel_areas and surface_regions of the valid pixels, from two compiled passes over the
    neighbours (rig.kernels.regions); `max_jump_mm` one distance, or one per pixel (H, W) for the step
    from it to the next. With `split_support`, the pixels on the support plane (support_plane) are
    regions apart from the rest."""
    if grid.shape[:2] != valid.shape:
        raise ValueError(f"grid {grid.shape} and valid {valid.shape}: one pixel grid, please")
    # One layout and one writability for the compiled loop: no extra compiled versions.
    limit = np.require(np.broadcast_to(np.asarray(max_jump_mm, np.float64), valid.shape), np.float64, ["C", "W"])
    grid, valid = (
        np.require(grid, None, ["C", "W"]),
        np.require(valid, np.bool_, ["C", "W"]),
    )  # truth arrays are read-only
    right, down, area = region_kernels.joins_and_areas(grid, valid, limit)
    if split_support:  # the object and its support meet, but are two regions
        on = support_plane(grid, valid)
        right &= on[:, 1:] == on[:, :-1]
        down &= on[1:, :] == on[:-1, :]
    return area[valid], region_kernels.joined_labels(right, down, valid)


def support_plane(grid: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(H, W) bool: the valid pixels whose points lie within SUPPORT_SPACINGS pixel spacings (the
    median distance between neighbouring points) of the view's largest plane, where that plane
    holds SUPPORT_SHARE of the valid pixels within one spacing; all False where no plane does. The
    plane is found by a fixed-seed RANSAC on a sample and refit to its inliers (the same view, the
    same plane)."""
    on = np.zeros(valid.shape, dtype=bool)
    flat = np.flatnonzero(valid)
    if len(flat) < 3:
        return on
    rows = slice(None, None, max(1, valid.shape[0] // 64))  # a few dozen rows tell the spacing
    pairs = valid[rows, 1:] & valid[rows, :-1]
    steps = np.linalg.norm(grid[rows, 1:] - grid[rows, :-1], axis=-1)[pairs]
    steps = steps[np.isfinite(steps)]
    tolerance = SUPPORT_SPACINGS * float(np.median(steps)) if len(steps) else 0.0
    if not tolerance > 0:  # no spacing to scale by (scattered pixels): no plane either
        return on
    rng = np.random.default_rng(0)
    points = grid.reshape(-1, 3)
    sample = points[rng.choice(flat, min(len(flat), _SUPPORT_SAMPLE), replace=False)].astype(np.float64)
    corners = sample[rng.integers(0, len(sample), (_SUPPORT_TRIALS, 3))]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    usable = lengths > 1e-12
    if not usable.any():
        return on
    normals, corners = normals[usable] / lengths[usable, None], corners[usable]
    offsets = np.einsum("ij,ij->i", normals, corners[:, 0])
    # Scored within one spacing: a plane holds its points that close, a curved surface only a band.
    tight = tolerance / SUPPORT_SPACINGS
    best = int(np.argmax((np.abs(sample @ normals.T - offsets) <= tight).sum(axis=0)))
    inliers = sample[np.abs(sample @ normals[best] - offsets[best]) <= tight]
    if len(inliers) < 3:
        return on
    centre = inliers.mean(axis=0)
    normal = np.linalg.svd(inliers - centre, full_matrices=False)[2][2]
    distance = _plane_distances(points, flat, normal, float(centre @ normal))
    if (distance <= tight).sum() >= SUPPORT_SHARE * len(flat):
        on.ravel()[flat] = distance <= tolerance
    return on


def _plane_distances(points: np.ndarray, rows: np.ndarray, normal: np.ndarray, offset: float) -> np.ndarray:
    """|points[rows] . normal - offset| (inf for a NaN point), a block of rows at a time: over a
    whole view at once its float64 temporaries were several times the scan's frames."""
    distance = np.empty(len(rows))
    for start in range(0, len(rows), _BLOCK_ROWS):
        part = distance[start : start + _BLOCK_ROWS]
        np.matmul(points[rows[start : start + _BLOCK_ROWS]], normal, out=part)
        np.abs(np.subtract(part, offset, out=part), out=part)
    distance[np.isnan(distance)] = np.inf
    return distance


def joined_labels(right: np.ndarray, down: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """A label per valid pixel (row-major) of the graph joining each pixel to its right neighbour
    where `right` (H, W-1) and to the one below where `down` (H-1, W) (a join to a pixel not valid
    joins nothing); regions are numbered in the order of their first pixel."""
    height, width = valid.shape
    if right.shape != (height, max(width - 1, 0)) or down.shape != (max(height - 1, 0), width):
        raise ValueError(f"joins {right.shape}, {down.shape} do not fit pixels {valid.shape}")
    return region_kernels.joined_labels(right, down, np.ascontiguousarray(valid, np.bool_))


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float, order: np.ndarray | None = None) -> float:
    """The value below which a share `q` of the total weight lies (the lower value at a tie), the
    weights summed in float64; `order`: the values' stable ascending order, where known."""
    order = np.argsort(values, kind="stable") if order is None else order
    weights = np.asarray(weights, np.float64)
    return region_kernels.ordered_quantile(values, weights, order, np.zeros(0, np.int64), 0, q)


@dataclass(frozen=True)
class RegionError:
    area_mm2: float
    share: float  # of the whole surface's area
    quantile_mm: float  # the area-weighted quantile of the distance to the true surface
    rms_mm: float  # area-weighted
    max_mm: float

    def as_dict(self) -> dict[str, float]:
        return {k: round(v, 5) for k, v in self.__dict__.items()}


def region_errors(
    distances: np.ndarray, areas: np.ndarray, labels: np.ndarray, q: float, min_share: float = MIN_REGION_SHARE
) -> tuple[RegionError, list[RegionError]]:
    """The whole surface's area-weighted error, and each region's that holds at least `min_share`
    of the area, largest first. A region's points are never copied out: its sums come from one
    compiled pass over them all, its quantile from the whole's order restricted to it."""
    total, areas = float(areas.sum()), np.asarray(areas, np.float64)  # summed in float64
    order = np.argsort(distances, kind="stable")  # once: a region's own order is this one's, restricted to it
    # a scan's many specks are never visited one by one
    per_label = region_kernels.label_totals(labels, areas, int(labels.max(initial=-1)) + 1)
    large = np.flatnonzero(per_label >= min_share * total)
    slot = np.full(len(per_label), -1, np.int64)
    slot[large] = np.arange(1, len(large) + 1)
    sums = region_kernels.region_sums(distances, areas, labels, slot, len(large) + 1)
    whole = _error(sums, 0, total, weighted_quantile(distances, areas, q, order))
    regions = [
        _error(sums, k + 1, total, region_kernels.ordered_quantile(distances, areas, order, labels, int(label), q))
        for k, label in enumerate(large)
    ]
    return whole, sorted(regions, key=lambda r: -r.area_mm2)


def _error(sums: tuple[np.ndarray, np.ndarray, np.ndarray], k: int, total: float, quantile: float) -> RegionError:
    area, square, largest = (float(column[k]) for column in sums)
    rms = float(np.sqrt(square / area)) if area > 0 else 0.0
    return RegionError(area, area / total if total > 0 else 0.0, quantile, rms, largest)
