"""Normals of ring samples (rig.pipeline.surface): each sample's from the triangles it is in,
smoothed along its ring, and, where a sample sits on a crease, one per face corner."""

from __future__ import annotations

import numpy as np

from rig.lazy import lazy_module

normal_kernels = lazy_module("rig.kernels.normals")  # numba compiles on first use
cell_kernels = lazy_module("rig.kernels.cells")

# A corner normal further than CREASE_DEG from its face's normal may be a crease's (a sample at the
# foot of a wall, whose normal also leans up the wall): that face then bends by the normals of the
# sample's faces within SIDE_DEG of its own (its side of the crease) only.
CREASE_DEG = 30.0
SIDE_DEG = 45.0


def vertex_normals(tri: np.ndarray, face: np.ndarray, weight: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Each sample's normal: its triangles' unit normals `face` weighted by `weight`, 1 / their
    longest edge. A triangle's normal belongs half-way across to the next ring, so weighting each
    side by the inverse of its spacing interpolates the two sides' normals to the sample, also
    where the rings are unevenly spaced."""
    return accumulate_normals(tri, face * weight[:, None], directions)


def accumulate_normals(tri: np.ndarray, face: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Unit normals of the points of triangles `tri` (F, 3): the sum of the (weighted) `face`
    vectors of the triangles each is in; a point in none faces its camera ray `directions` back."""
    normals = corner_sums(tri, face, len(directions))
    normal_kernels.unit_or_facing(normals, np.ascontiguousarray(directions, np.float64))
    return normals


def ring_pairs(points: np.ndarray, xy: np.ndarray, ring: np.ndarray, radius_px: float) -> np.ndarray:
    """(P, 2) pairs of samples of one ring within `radius_px` in the image and as many pixel
    footprints in space (not across a bend the image foreshortens): the neighbours whose normals
    smoothed_normals averages."""
    if radius_px <= 0 or len(xy) < 2:
        return np.zeros((0, 2), np.int64)
    xy = np.ascontiguousarray(xy, np.float64)
    pairs = cell_kernels.pairs_within(xy, cell_kernels.sample_cells(xy, radius_px), radius_px, radius_px)
    a, b = pairs[:, 0], pairs[:, 1]
    apart_mm, apart_px = normal_kernels.pair_lengths(np.ascontiguousarray(points, np.float64), xy, pairs)
    footprint = np.median(apart_mm / np.maximum(apart_px, 1e-6))  # mm per pixel where the surface faces the camera
    return pairs[(ring[a] == ring[b]) & (apart_mm <= radius_px * footprint)]


def smoothed_normals(normals: np.ndarray, pairs: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Each sample's normal averaged with those of its `pairs` (ring_pairs) whose normals are
    `known` (from triangles). Along a ring samples are a pixel apart, so each triangle's short edge,
    and with it its normal, is mostly the samples' noise; the quadratic interpolant carries a
    normal's error across the whole gap to the next ring."""
    if len(pairs) == 0:
        return normals
    return normal_kernels.pair_smoothed(normals, pairs, known)


def corner_sums(tri: np.ndarray, vectors: np.ndarray, count: int) -> np.ndarray:
    """(count, 3): per point, the sum of the `vectors` rows (F, 3) of the triangles `tri` (F, 3) it
    is a corner of (a compiled loop: rig.kernels.normals)."""
    sums = np.zeros((count, 3))
    normal_kernels.corner_sums(np.ascontiguousarray(tri, np.int64), np.ascontiguousarray(vectors, np.float64), sums)
    return sums


def crease_normals(tri: np.ndarray, normals: np.ndarray, face: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """(F, 3, 3) each face corner's normal: the sample's own, or, where that is more than CREASE_DEG
    from the face's unit normal `face`, the `weight`ed mean of the unit normals of the faces around
    the sample that are within SIDE_DEG of this face (a crease splits a sample's normal in two)."""
    corner = np.take(normals, tri, axis=0)  # 0.65 ms for 68,000 faces; an index and a copy took 5.5
    limit = np.cos(np.radians(CREASE_DEG))
    split_face, split_k = np.nonzero(np.einsum("fkj,fj->fk", corner, face) < limit)
    if len(split_face) == 0:
        return corner
    # the faces of each sample, grouped: faces_of[start[v] : start[v] + count[v]]
    order = np.argsort(tri.ravel(), kind="stable")
    faces_of = order // 3
    count = np.bincount(tri.ravel(), minlength=len(normals))
    start = np.cumsum(count) - count
    sample = tri[split_face, split_k]
    n = count[sample]
    which = np.repeat(np.arange(len(sample)), n)
    other = faces_of[np.repeat(start[sample], n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    agree = np.einsum("ij,ij->i", face[other], face[split_face[which]]) >= np.cos(np.radians(SIDE_DEG))
    total = np.column_stack(
        [np.bincount(which, agree * weight[other] * face[other, j], minlength=len(sample)) for j in range(3)]
    )
    corner[split_face, split_k] = total / np.maximum(np.linalg.norm(total, axis=1), 1e-12)[:, None]
    return corner
