"""Errors of a surface by its area, region by region: what a tolerance promises on the object.

A surface measured per point or per pixel gives a flat background, which most pixels see, the
weight of the object on it, and a steep object side, which few pixels see, almost none. Here each
covered pixel of a camera grid counts the area of the surface it stands for (its footprint), and
the surface is split into connected regions wherever neighbouring pixels' points jump apart (a
depth step), so that an object and the bench it stands on are judged each on its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

MIN_REGION_SHARE = 0.05  # regions smaller than this share of the area are not judged on their own


def pixel_areas(grid: np.ndarray, valid: np.ndarray, max_jump_mm: float) -> np.ndarray:
    """The area (mm^2) of surface each valid pixel of `grid` (H, W, 3) stands for, from the cross
    product of its steps to the neighbouring pixels' points (central where both exist, one-sided at
    an edge or a depth step over `max_jump_mm`, which is no part of either surface); a pixel with no
    such neighbour along a direction takes its other direction's step."""
    du = _step(grid, valid, 1, max_jump_mm)
    dv = _step(grid, valid, 0, max_jump_mm)
    area = np.linalg.norm(np.cross(du, dv), axis=-1)  # NaN where a direction is unknown
    lengths_u, lengths_v = np.linalg.norm(du, axis=-1), np.linalg.norm(dv, axis=-1)
    square = np.where(np.isfinite(lengths_u), lengths_u, lengths_v) ** 2  # one direction known: a square pixel
    area = np.where(np.isfinite(area), area, square)
    return np.nan_to_num(area[valid], nan=0.0)


def _step(grid: np.ndarray, valid: np.ndarray, axis: int, max_jump_mm: float) -> np.ndarray:
    """Per pixel, the step (mm, 3-vector) to the next pixel's point along `axis`: the mean of the
    two one-sided differences where both neighbours are valid and near, else the one there is, else
    NaN."""
    forward = np.full(grid.shape, np.nan)
    backward = np.full(grid.shape, np.nan)
    ahead = [slice(None)] * 2
    behind = [slice(None)] * 2
    ahead[axis], behind[axis] = slice(1, None), slice(None, -1)
    diff = grid[tuple(ahead)] - grid[tuple(behind)]
    both = valid[tuple(ahead)] & valid[tuple(behind)] & (np.linalg.norm(diff, axis=-1) <= max_jump_mm)
    diff = np.where(both[..., None], diff, np.nan)
    forward[tuple(behind)] = diff
    backward[tuple(ahead)] = diff
    central = (forward + backward) / 2
    return np.where(np.isfinite(central), central, np.where(np.isfinite(forward), forward, backward))


def surface_regions(grid: np.ndarray, valid: np.ndarray, max_jump_mm: float) -> np.ndarray:
    """A region label per valid pixel: pixels joined through 4-neighbours whose points lie within
    `max_jump_mm` of each other, so a depth step separates the surfaces on its two sides."""
    index = np.full(valid.shape, -1)
    index[valid] = np.arange(int(valid.sum()))
    rows, cols = [], []
    for ahead, behind in (
        ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
        ((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
    ):
        both = valid[ahead] & valid[behind]
        near = np.linalg.norm(grid[ahead] - grid[behind], axis=-1) <= max_jump_mm
        joined = both & near
        rows.append(index[behind][joined])
        cols.append(index[ahead][joined])
    count = int(valid.sum())
    edges = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(edges[0]), np.int8), edges), shape=(count, count))
    _, labels = connected_components(graph, directed=False)
    return labels


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The value below which a share `q` of the total weight lies (the lower value at a tie)."""
    order = np.argsort(values, kind="stable")
    cumulative = np.cumsum(weights[order])
    at = int(np.searchsorted(cumulative, q * cumulative[-1], side="left"))
    return float(values[order][min(at, len(values) - 1)])


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
    of the area, largest first."""
    whole = _error(distances, areas, areas.sum(), q)
    regions = []
    for label in np.unique(labels):
        inside = labels == label
        if areas[inside].sum() >= min_share * areas.sum():
            regions.append(_error(distances[inside], areas[inside], areas.sum(), q))
    return whole, sorted(regions, key=lambda r: -r.area_mm2)


def _error(distances: np.ndarray, areas: np.ndarray, total: float, q: float) -> RegionError:
    area = float(areas.sum())
    rms = float(np.sqrt(np.sum(areas * distances.astype(np.float64) ** 2) / area)) if area > 0 else 0.0
    return RegionError(area, area / total if total > 0 else 0.0, weighted_quantile(distances, areas, q), rms,
                       float(distances.max()))  # fmt: skip
