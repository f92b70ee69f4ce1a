"""Delaunay triangles of image points (ring samples): compiled incremental insertion
(rig.kernels.delaunay) in a biased randomised order, with SciPy's Qhull where it gives up.

The order matters more than anything else in the insertion. Ring samples lie a pixel apart along
their rings and ten or more across, so a point inserted among its neighbours in plain curve order
(which OpenCV's Subdiv2D used to get) first joins long thin triangles that its neighbours' arrival
flips again: 9.5 flips a point on the default bench's 37 000 samples. In random order the edges a
point's arrival makes number under six on average whatever the points (backward analysis): three
by its split, under three by flips; but every walk to it is long. Rounds of doubling size, each
along a Hilbert curve (Amenta, Choi and Rote's BRIO), keep both: 11 ms against 18-25 for the curve
alone and 64-86 for Subdiv2D (throwaway timings, one thread).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError

from rig.kernels import bounds
from rig.lazy import lazy_module

delaunay_kernels = lazy_module("rig.kernels.delaunay")  # numba compiles on first use
cell_kernels = lazy_module("rig.kernels.cells")

_HILBERT_BITS = 10  # a 1024 x 1024 grid over the points' bounding box: a few samples per cell
_FIRST_ROUND = 64  # points in the smallest round of the insertion order, about
_ENCLOSING = 100.0  # the enclosing triangle's size in spans of the points: few hull triangles lost


def delaunay(xy: np.ndarray) -> np.ndarray:
    """Delaunay triangles (F, 3) of image points (N, 2), counter-clockwise in the image's x-y axes,
    but a few long thin ones along the convex hull; points that coincide are triangulated once, as
    the first of them, and none for points exactly on one line. Inserted one at a time
    (rig.kernels.delaunay) in `insertion_order`; where rounding leaves the triangles short of
    Delaunay and a walk goes round in a circle, Qhull (no ring scan has needed it). ValueError for
    a coordinate that is not finite."""
    if not np.isfinite(xy).all():
        raise ValueError("Delaunay triangles of points with a coordinate that is not finite")
    if len(xy) < 3:
        return np.zeros((0, 3), np.int64)
    order = insertion_order(xy)
    lo, hi = bounds(xy)
    middle, span = (lo + hi) / 2, _ENCLOSING * (float((hi - lo).max()) + 1.0)
    enclosing = middle + span * np.array([[-2.0, -1.0], [2.0, -1.0], [0.0, 2.0]])  # counter-clockwise
    ordered = np.ascontiguousarray(np.vstack([xy[order], enclosing]), np.float64)  # neighbours in memory too
    corners = np.empty((2 * len(xy) + 1, 3), np.int64)
    count = delaunay_kernels.insert_all(ordered, order, corners)
    return corners[:count] if count >= 0 else _qhull(np.asarray(xy, np.float64))


def insertion_order(xy: np.ndarray, bits: int = _HILBERT_BITS) -> np.ndarray:
    """The points (N, 2) in rounds of doubling size, each along a Hilbert curve over their bounding
    box (rig.kernels.delaunay.hilbert_distances): the last round holds about half the points, the
    one before a quarter, and so on. A point's round comes from a hash of its coordinates, not a
    random draw: the order is the same on every run, and coinciding points share a round and keep
    their own order (the first of them is inserted, the rest are found equal to it)."""
    xy = np.ascontiguousarray(xy, np.float64) + 0.0  # -0.0 as 0.0: equal points, equal bits
    last = max(int(np.log2(max(len(xy), 1) / _FIRST_ROUND)), 0)
    rounds_before = np.minimum(_trailing_zero_bits(xy), last)  # 0 for half the points, 1 for a quarter, ...
    curve = delaunay_kernels.hilbert_distances(xy, bits)
    keys = (last - rounds_before) << (2 * bits) | curve
    return cell_kernels.radix_order(keys, 2 * bits + max(last, 1).bit_length())  # np.argsort's stable order


def _trailing_zero_bits(xy: np.ndarray) -> np.ndarray:
    """Per point, the trailing zero bits of its coordinates' bits mixed by splitmix64's finaliser:
    a geometric count (0 with probability 1/2, 1 with 1/4, ...) that equal points share."""
    bits = xy.view(np.uint64)
    key = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ bits[:, 1]
    for shift, factor in ((30, 0xBF58476D1CE4E5B9), (27, 0x94D049BB133111EB)):
        key = (key ^ (key >> np.uint64(shift))) * np.uint64(factor)
    key ^= key >> np.uint64(31)
    lowest = (key & (~key + np.uint64(1))).astype(np.float64)  # the lowest set bit alone
    return np.log2(np.maximum(lowest, 1.0)).astype(np.int64)


def _qhull(xy: np.ndarray) -> np.ndarray:
    """Qhull's Delaunay triangles, counter-clockwise, of the first of each set of coinciding points."""
    _, first = np.unique(xy, axis=0, return_index=True)
    first = np.sort(first)
    try:
        tri = first[Delaunay(xy[first]).simplices]
    except QhullError:
        return np.zeros((0, 3), np.int64)
    a, b, c = (xy[tri[:, k]] for k in range(3))
    clockwise = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    tri[clockwise] = tri[clockwise][:, ::-1]
    return tri.astype(np.int64)
