"""Delaunay triangles of image points (rig.pipeline.triangulation), compiled by numba: points inserted
one at a time into a triangle enclosing them all, each found by walking from the last (Lawson's
incremental algorithm; in rounds along a space-filling curve, rig.pipeline.triangulation, each walk
is a few steps).

A point splits the triangle it falls in into three (or, on an edge, the two beside it into four),
and each edge opposite it that fails the empty-circle test is flipped, which exposes two more to
test. Triangles are kept as half-edges: half-edge h of triangle h // 3 runs from corner h to the
next corner, and `twins[h]` is the same edge run the other way in the neighbouring triangle (-1 on
the enclosing triangle). Triangles touching the enclosing triangle's corners are left out at the
end, so a few long thin ones along the points' convex hull are missing.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL

# A point lying this close to a circle (relative to the test's own rounding bound, Shewchuk's
# ~2e-15 of its terms' magnitude) counts as on it, and its edge is not flipped: with four points on
# one circle either diagonal is Delaunay, and flipping on rounding noise made points all on one
# circle flip about every edge at every arrival.
_ON_CIRCLE = 1e-12


@njit(**KERNEL)
def insert_all(xy: np.ndarray, names: np.ndarray, corners: np.ndarray) -> int:
    """Delaunay triangles of points `xy` (N + 3, 2; the last three a counter-clockwise triangle
    around the others), inserted in the order of the rows, into the first rows of `corners` (at
    least (2N + 1, 3)): counter-clockwise, those touching the enclosing three left out, each point
    by its name in `names` (N,); returns their count. A point equal to a corner of the triangle it
    falls in is left out, so the first of coinciding points is the one kept. -1 where a walk visits
    more triangles than there are (it went round in a circle: rounding left the triangles short of
    Delaunay)."""
    size = len(xy) - 3
    tri = corners.reshape(-1)  # a view, or an error: never a copy the caller would not see
    twins = np.full(len(tri), -1, np.int64)
    stack = np.empty(len(tri) + 4, np.int64)  # a point's four edges, and two more for each flip at most
    count = _add(tri, twins, 0, (size, size + 1, size + 2), (-1, -1, -1))
    last = 0
    for p in range(size):
        t, on_edge = _locate(xy, tri, twins, p, last, count)
        if t < 0:
            return -1
        if _same(xy, p, tri[3 * t]) or _same(xy, p, tri[3 * t + 1]) or _same(xy, p, tri[3 * t + 2]):
            continue
        if on_edge >= 0 and twins[on_edge] >= 0:
            count = _split_edge(tri, twins, count, on_edge, p, stack)
            pending = 4
        else:
            count = _split_triangle(tri, twins, count, t, p, stack)
            pending = 3
        _legalise(xy, tri, twins, stack, pending)
        last = t
    kept = 0
    for t in range(count):  # in place: row `kept` is never ahead of row t
        a, b, c = corners[t, 0], corners[t, 1], corners[t, 2]
        if a < size and b < size and c < size:
            corners[kept, 0], corners[kept, 1], corners[kept, 2] = names[a], names[b], names[c]
            kept += 1
    return kept


@njit(**KERNEL)
def _locate(xy: np.ndarray, tri: np.ndarray, twins: np.ndarray, p: int, start: int, count: int) -> tuple[int, int]:
    """The triangle point p lies in, walked to from triangle `start` across each edge p lies
    strictly beyond, and the half-edge p lies on (-1 for none). In a Delaunay triangulation such a
    walk never enters a triangle twice; (-1, -1) after more steps than the `count` triangles."""
    t = start
    for _ in range(count + 1):
        moved = False
        on_edge = -1
        for j in range(3):
            h = 3 * t + j
            side = _side(xy, tri[h], tri[3 * t + (j + 1) % 3], p)
            if side < 0.0 and twins[h] >= 0:
                t = twins[h] // 3
                moved = True
                break
            if side == 0.0:
                on_edge = h
        if not moved:
            return t, on_edge
    return -1, -1


@njit(**KERNEL)
def _split_triangle(tri: np.ndarray, twins: np.ndarray, count: int, t: int, p: int, stack: np.ndarray) -> int:
    """Triangle t (a, b, c) becomes (a, b, p), and (b, c, p), (c, a, p) are added; their outer
    edges go on `stack` for the empty-circle test."""
    h = 3 * t
    a, b, c = tri[h], tri[h + 1], tri[h + 2]
    outer_bc, outer_ca = twins[h + 1], twins[h + 2]
    u, v = 3 * count, 3 * count + 3
    tri[h + 2] = p
    count = _add(tri, twins, count, (b, c, p), (outer_bc, -1, h + 1))
    count = _add(tri, twins, count, (c, a, p), (outer_ca, h + 2, u + 1))
    stack[0], stack[1], stack[2] = h, u, v
    return count


@njit(**KERNEL)
def _split_edge(tri: np.ndarray, twins: np.ndarray, count: int, h: int, p: int, stack: np.ndarray) -> int:
    """Point p on half-edge h (a -> b, in (a, b, c)) and its twin (b -> a, in (b, a, d)): the two
    become (a, p, c), (b, p, d) in place and (p, b, c), (p, a, d) are added; their outer edges go on
    `stack`."""
    g = twins[h]
    (h_next, h_prev), (g_next, g_prev) = _turns(h), _turns(g)
    a, b, c, d = tri[h], tri[h_next], tri[h_prev], tri[g_prev]
    outer_bc, outer_ad = twins[h_next], twins[g_next]
    # (a, b, c) -> (a, p, c): h runs a->p, h_next p->c, h_prev c->a as before
    tri[h_next] = p
    # (b, a, d) -> (b, p, d): g runs b->p, g_next p->d, g_prev d->b as before
    tri[g_next] = p
    first = 3 * count
    count = _add(tri, twins, count, (p, b, c), (g, outer_bc, h_next))  # p->b twins b->p (g)
    count = _add(tri, twins, count, (p, a, d), (h, outer_ad, g_next))  # p->a twins a->p (h)
    stack[0], stack[1], stack[2], stack[3] = h_prev, g_prev, first + 1, first + 4
    return count


@njit(**KERNEL)
def _side(xy: np.ndarray, a: int, b: int, p: int) -> float:
    """Positive where p lies left of a -> b, negative right, zero on its line."""
    return (xy[b, 0] - xy[a, 0]) * (xy[p, 1] - xy[a, 1]) - (xy[b, 1] - xy[a, 1]) * (xy[p, 0] - xy[a, 0])


@njit(**KERNEL)
def _add(tri: np.ndarray, twins: np.ndarray, count: int, corners: tuple, across: tuple) -> int:
    """Append triangle `corners` (a, b, c), its half-edges a->b, b->c, c->a twinned with `across`."""
    t = 3 * count
    for j in range(3):
        tri[t + j] = corners[j]
        _twin(twins, t + j, across[j])
    return count + 1


@njit(nogil=True, cache=True, inline="always")
def _turns(h: int) -> tuple[int, int]:
    """The next and the previous half-edge of half-edge h's triangle."""
    first = h - h % 3
    return first + (h + 1) % 3, first + (h + 2) % 3


@njit(**KERNEL)
def _same(xy: np.ndarray, p: int, q: int) -> bool:
    return xy[p, 0] == xy[q, 0] and xy[p, 1] == xy[q, 1]


@njit(**KERNEL)
def _twin(twins: np.ndarray, a: int, b: int) -> None:
    """Half-edges a and b run along one edge the two ways (b -1: a lies on the enclosing triangle)."""
    twins[a] = b
    if b >= 0:
        twins[b] = a


@njit(**KERNEL)
def _legalise(xy: np.ndarray, tri: np.ndarray, twins: np.ndarray, stack: np.ndarray, pending: int) -> int:
    """Flip the first `pending` half-edges of `stack` (each opposite the new point in its triangle),
    and those each flip exposes, while the point across lies inside the circle of the triangle on
    this side; returns the flips. Each flip takes one edge off the stack and puts two on, and adds
    an edge at the new point, so the stack never holds more than the half-edges plus four."""
    top, flips = pending, 0
    while top > 0:
        top -= 1
        a = stack[top]
        b = twins[a]
        if b < 0:
            continue
        (a_next, a_prev), (b_next, b_prev) = _turns(a), _turns(b)
        p0, pr, pl, p1 = tri[a_prev], tri[a], tri[a_next], tri[b_prev]
        if not _in_circle(xy, p0, pr, pl, p1):
            continue
        # the quad p0 pr p1 pl: triangles (p0 pr pl), (pl pr p1) become (p1 pl p0), (p0 pr p1)
        tri[a], tri[b] = p1, p0
        outer_b, outer_a = twins[b_prev], twins[a_prev]
        _twin(twins, a, outer_b)
        _twin(twins, b, outer_a)
        _twin(twins, a_prev, b_prev)
        flips += 1
        stack[top], stack[top + 1] = a, b_next  # the quad's far edges, now opposite p0
        top += 2
    return flips


@njit(**KERNEL)
def _in_circle(xy: np.ndarray, a: int, b: int, c: int, d: int) -> bool:
    """Whether d lies inside the circle through the counter-clockwise a, b, c by more than rounding."""
    ax, ay = xy[a, 0] - xy[d, 0], xy[a, 1] - xy[d, 1]
    bx, by = xy[b, 0] - xy[d, 0], xy[b, 1] - xy[d, 1]
    cx, cy = xy[c, 0] - xy[d, 0], xy[c, 1] - xy[d, 1]
    a2, b2, c2 = ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy
    ab, bc, ca = ax * by - bx * ay, bx * cy - cx * by, cx * ay - ax * cy
    bound = a2 * (abs(bx * cy) + abs(cx * by)) + b2 * (abs(cx * ay) + abs(ax * cy)) + c2 * (abs(ax * by) + abs(bx * ay))
    return a2 * bc + b2 * ca + c2 * ab > _ON_CIRCLE * bound


@njit(**KERNEL)
def hilbert_distances(xy: np.ndarray, bits: int) -> np.ndarray:
    """Each point's distance along a Hilbert curve over a grid of 2^bits x 2^bits cells spanning the
    points' bounding box (its longer side): consecutive points along it are close in the image."""
    x0, y0 = xy[:, 0].min(), xy[:, 1].min()
    span = max(max(xy[:, 0].max() - x0, xy[:, 1].max() - y0), 1e-9)
    cells = (1 << bits) - 1
    distance = np.zeros(len(xy), np.int64)
    for i in range(len(xy)):
        x, y = int((xy[i, 0] - x0) * (cells / span)), int((xy[i, 1] - y0) * (cells / span))
        side = 1 << (bits - 1)
        while side > 0:  # the curve's quadrant at each scale, then the quadrant's turn for the next
            right, upper = (x & side) > 0, (y & side) > 0
            distance[i] += side * side * ((3 * right) ^ upper)
            if not upper:
                if right:
                    x, y = side - 1 - x, side - 1 - y
                x, y = y, x
            side //= 2
    return distance
