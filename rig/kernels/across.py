"""The across-ring test's verdicts (rig.pipeline.ring_triangulation.across_ring_support), compiled
by numba: the samples that share one neighbourhood of candidates (those within reach of one
candidate of their own ring) share its neighbours of other rings, so its planes are fitted once, in
coordinates about the neighbourhood's own sample, and each sample of it is judged by the planes'
heights at its own position. The GIL released, a range of samples per call."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig.kernels import KERNEL

# A fitted plane: (fitted, height a, slopes b and c, scatter), z = a + b dx + c dy about the anchor.
Plane = tuple[bool, float, float, float, float]


@njit(nogil=True, cache=True)
def _plane(near: np.ndarray, part: np.ndarray, count: int, min_count: int) -> Plane:
    """The plane z = a + b dx + c dy fitted to the neighbours near[:count] (dx, dy, z) in `part`,
    with its scatter (rms off it, over n - 3); not fitted with fewer than `min_count` of them."""
    n = sx = sy = sxx = sxy = syy = sz = sxz = syz = 0.0
    for j in range(count):
        if part[j]:
            dx, dy, z = near[j, 0], near[j, 1], near[j, 2]
            n += 1.0
            sx += dx
            sy += dy
            sxx += dx * dx
            sxy += dx * dy
            syy += dy * dy
            sz += z
            sxz += dx * z
            syz += dy * z
    if n < min_count:
        return False, 0.0, 0.0, 0.0, np.inf
    # the normal equations (ridged by 1e-6) solved by Cramer's rule
    a11, a22, a33 = n + 1e-6, sxx + 1e-6, syy + 1e-6
    minor1, minor2, minor3 = a22 * a33 - sxy * sxy, sx * a33 - sxy * sy, sx * sxy - a22 * sy
    det = a11 * minor1 - sx * minor2 + sy * minor3
    c0 = (sz * minor1 - sx * (sxz * a33 - sxy * syz) + sy * (sxz * sxy - a22 * syz)) / det
    c1 = (a11 * (sxz * a33 - sxy * syz) - sz * minor2 + sy * (sx * syz - sxz * sy)) / det
    c2 = (a11 * (a22 * syz - sxz * sxy) - sx * (sx * syz - sxz * sy) + sz * minor3) / det
    squares = 0.0
    for j in range(count):
        if part[j]:
            off = near[j, 2] - (c0 + c1 * near[j, 0] + c2 * near[j, 1])
            squares += off * off
    return True, c0, c1, c2, math.sqrt(squares / max(n - 3.0, 1.0))


@njit(nogil=True, cache=True)
def _predicts(plane: Plane, dx: float, dy: float, depth: float, max_jump: float, max_scatter: float) -> bool:
    """Whether a fitted plane of scatter at most `max_scatter` puts the point at (dx, dy) about the
    anchor within `max_jump`, or four times the scatter, of its `depth`."""
    fitted, a, b, c, scatter = plane
    return fitted and scatter <= max_scatter and abs(depth - (a + b * dx + c * dy)) <= max(max_jump, 4.0 * scatter)


@njit(nogil=True, cache=True)
def _split(
    near: np.ndarray, near_ring: np.ndarray, count: int, sides: tuple[np.ndarray, np.ndarray]
) -> tuple[bool, bool]:
    """The neighbours split at the largest gap in their depths into `sides` (below, above: masks);
    for each side, whether it is of one ring alone (a curve: it fixes no plane, so cannot judge)."""
    below, above = sides
    z = np.sort(near[:count, 2])
    split = np.argmax(z[1:] - z[:-1]) if count > 1 else 0
    threshold = 0.5 * (z[split] + z[split + 1]) if count > 1 else np.nan
    for j in range(count):
        below[j] = near[j, 2] <= threshold
        above[j] = not below[j]
    alone = [False, False]
    for k in range(2):
        side = sides[k]
        members, first_ring, one_ring = 0, -1, True
        for j in range(count):
            if side[j]:
                members += 1
                first_ring = near_ring[j] if first_ring < 0 else first_ring
                one_ring = one_ring and near_ring[j] == first_ring
        alone[k] = members > 0 and one_ring
    return alone[0], alone[1]


@njit(**KERNEL)
def across_agrees(
    points: tuple[np.ndarray, np.ndarray, np.ndarray],
    neighbourhoods: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    judged: np.ndarray,
    limits: tuple[float, int, int],
    out: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.ring_triangulation.across_ring_support for the points judged[start:stop], in the
    order of their neighbourhoods: out[i] False where point p = judged[i]'s nearest `neighbours`
    candidates of other rings still alive (index[row[p]] of a ring other than its own, nearest
    first) span two rings or more, are `min_count` or more, and neither one plane over them (scatter
    at most half the limit) nor a plane over either side of their largest depth gap predicts it
    within `max_jump`. points = (xy, depth, ring); neighbourhoods = (index, row, anchors: each row's
    own sample's xy, alive); limits = (max_jump, neighbours, min_count)."""
    xy, depth, ring = points
    index, row, anchors, alive = neighbourhoods
    max_jump, neighbours, min_count = limits
    near = np.empty((neighbours, 3))
    near_ring = np.empty(neighbours, np.int64)
    every, below, above = np.ones(neighbours, np.bool_), np.empty(neighbours, np.bool_), np.empty(neighbours, np.bool_)
    unfitted = (False, 0.0, 0.0, 0.0, np.inf)
    current, count, judgeable, sided = -1, 0, False, False
    whole, low, high, low_alone, high_alone = unfitted, unfitted, unfitted, False, False
    for i in range(start, stop):
        p = judged[i]
        r = row[p]
        if r != current:  # a new neighbourhood: its neighbours of other rings and their plane
            current, count, sided = r, 0, False
            for j in range(index.shape[1]):
                q = index[r, j]
                if ring[q] != ring[p] and alive[q] and count < neighbours:
                    near[count, 0], near[count, 1] = xy[q, 0] - anchors[r, 0], xy[q, 1] - anchors[r, 1]
                    near[count, 2], near_ring[count] = depth[q], ring[q]
                    count += 1
            judgeable = count >= min_count and near_ring[:count].min() < near_ring[:count].max()
            if judgeable:
                whole = _plane(near, every, count, min_count)
        if not judgeable:
            out[i] = True
            continue
        dx, dy = xy[p, 0] - anchors[r, 0], xy[p, 1] - anchors[r, 1]
        if _predicts(whole, dx, dy, depth[p], max_jump, 0.5 * max_jump):
            out[i] = True
            continue
        if not sided:  # the two sides of the depth gap, fitted once the one plane fails a point
            low_alone, high_alone = _split(near, near_ring, count, (below, above))
            low, high = _plane(near, below, count, min_count), _plane(near, above, count, min_count)
            sided = True
        out[i] = (
            low_alone
            or _predicts(low, dx, dy, depth[p], max_jump, np.inf)
            or high_alone
            or _predicts(high, dx, dy, depth[p], max_jump, np.inf)
        )
