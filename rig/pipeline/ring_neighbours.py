"""The projector angle a ring sample's placed neighbours predict for it (rig.pipeline.ring_angles
reads an ambiguous sample again with it): a plane over the image fitted to the angles of the nearest
samples of its own ring, searched in each ring's own grid of cells."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rig.lazy import lazy_module
from rig.workers import batches, pool

cell_kernels = lazy_module("rig.kernels.cells")  # numba compiles on first use: not for --help

# The nearest NEIGHBOUR_COUNT placed samples of a sample's ring within NEIGHBOUR_REACH_PX in the image.
NEIGHBOUR_COUNT = 8
NEIGHBOUR_REACH_PX = 12.0
_SLOPE_RIDGE = 1e-3  # holds a plane's unfixed slope near zero (radians per pixel, squared pixels)


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return np.mod(angle + np.pi, 2 * np.pi) - np.pi


def neighbour_angles(
    xy: np.ndarray,
    ring: np.ndarray,
    angle_of: Callable[[np.ndarray], np.ndarray],
    at_xy: np.ndarray,
    at_ring: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The projector angle at image points `at_xy` of rings `at_ring`, from the angles of samples
    (`xy`, `ring`) of the same ring within NEIGHBOUR_REACH_PX: a plane over the image fitted to the
    nearest NEIGHBOUR_COUNT (at least 3; the slope across a straight run of ring, which its samples
    cannot fix, held near zero). `angle_of(indices)`: the angles of those samples, asked only of
    the neighbours found (the few that ambiguous samples have, not every sample). Returns the
    prediction and the fit's rms (NaN where too few neighbours)."""
    dist, near = _same_ring_nearest(xy, ring, at_xy, at_ring)
    found = np.isfinite(dist)
    near = np.where(found, near, 0)
    angle = np.zeros(len(xy))
    asked = np.unique(near)
    angle[asked] = angle_of(asked)
    offset = np.where(found[..., None], xy[near] - at_xy[:, None, :], 0.0)  # (n, k, 2)
    # angles relative to the first neighbour's, so the fit never meets the wrap at +-pi
    base = angle[near[:, 0]]
    value = np.where(found, wrap_angle(angle[near] - base[:, None]), 0.0)
    design = np.concatenate([found[..., None].astype(np.float64), offset], axis=2)
    normal = np.einsum("nki,nkj->nij", design, design) + np.diag([0.0, _SLOPE_RIDGE, _SLOPE_RIDGE])
    rhs = np.einsum("nki,nk->ni", design, value)
    enough = found.sum(axis=1) >= 3
    coef = np.full((len(at_xy), 3), np.nan)
    coef[enough] = np.linalg.solve(normal[enough], rhs[enough][..., None])[..., 0]
    fitted = np.einsum("nki,ni->nk", design, np.nan_to_num(coef))
    scatter = np.sqrt(np.sum(np.where(found, (fitted - value) ** 2, 0.0), axis=1) / np.maximum(found.sum(axis=1), 1))
    return np.where(enough, wrap_angle(base + coef[:, 0]), np.nan), np.where(enough, scatter, np.nan)


def _same_ring_nearest(
    xy: np.ndarray, ring: np.ndarray, at_xy: np.ndarray, at_ring: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(n, NEIGHBOUR_COUNT) distances and indices of the samples (`xy`, `ring`) of each query's ring
    within NEIGHBOUR_REACH_PX, nearest first (inf where fewer): the rings' own grids of cells
    (rig.kernels.cells.group_cells), searched a span of queries per thread."""
    xy = np.ascontiguousarray(xy, np.float64)
    at_xy = np.ascontiguousarray(at_xy, np.float64)
    rings = int(max(ring.max(initial=0), at_ring.max(initial=0))) + 1
    side = cell_kernels.group_cell_side(xy, rings, NEIGHBOUR_REACH_PX)
    cells = cell_kernels.group_cells(xy, ring.astype(np.int64), rings, side)
    dist, near = np.empty((len(at_xy), NEIGHBOUR_COUNT)), np.empty((len(at_xy), NEIGHBOUR_COUNT), np.int64)
    where, groups = (side, NEIGHBOUR_REACH_PX), at_ring.astype(np.int64)
    list(
        pool().map(
            lambda span: cell_kernels.k_nearest_in_group(cells, where, at_xy, groups, dist, near, *span),
            batches(len(at_xy)),
        )
    )
    return dist, near
