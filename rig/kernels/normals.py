"""The ring samples' normals (rig.pipeline.normals) and the ring triangles' bend tests
(rig.pipeline.ring_faces), compiled by numba: sums over faces and pairs in one loop each, in numpy's
bincount order (every face's corner 0, then 1, then 2), so the sums are numpy's to the last bit.
As numpy passes they took a fifth of the ring surface's triangles (scratch profile, default bench).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL
from rig.kernels.vectors import corner_cross, row_dot


@njit(**KERNEL)
def corner_sums(tri: np.ndarray, vectors: np.ndarray, sums: np.ndarray) -> None:
    """Add each face's `vectors` row (F, 3) to the `sums` row (M, 3) of each of its corners `tri` (F, 3)."""
    for k in range(3):
        for f in range(len(tri)):
            v = tri[f, k]
            for c in range(3):
                sums[v, c] += vectors[f, c]


@njit(**KERNEL)
def area_faces(
    points: np.ndarray,
    xy: np.ndarray,
    directions: np.ndarray,
    tri: np.ndarray,
    max_edge_px: float,
    face: np.ndarray,
    short: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.ring_triangulation.sample_normals' triangles [start:stop]: each one's area-weighted
    normal toward the camera into `face` (F, 3), and whether its longest edge in the image (`xy`) is
    within `max_edge_px` into `short` (F,)."""
    for f in range(start, stop):
        longest = 0.0
        for k in range(3):
            a, b = tri[f, k], tri[f, (k + 2) % 3]
            longest = max(longest, np.sqrt((xy[a, 0] - xy[b, 0]) ** 2 + (xy[a, 1] - xy[b, 1]) ** 2))
        short[f] = longest <= max_edge_px
        p0 = tri[f, 0]
        nx, ny, nz = corner_cross(points, p0, tri[f, 1], tri[f, 2])
        flip = -1.0 if nx * directions[p0, 0] + ny * directions[p0, 1] + nz * directions[p0, 2] > 0 else 1.0
        face[f, 0], face[f, 1], face[f, 2] = flip * nx, flip * ny, flip * nz


@njit(**KERNEL)
def unit_or_facing(sums: np.ndarray, directions: np.ndarray) -> None:
    """Scale each row of `sums` (M, 3) to unit length in place; a row of (almost) nothing becomes its
    camera ray `directions` reversed (facing the camera)."""
    for v in range(len(sums)):
        norm = np.sqrt(sums[v, 0] ** 2 + sums[v, 1] ** 2 + sums[v, 2] ** 2)
        for c in range(3):
            sums[v, c] = -directions[v, c] if norm < 1e-12 else sums[v, c] / norm


@njit(**KERNEL)
def pair_smoothed(normals: np.ndarray, pairs: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(M, 3) each of `normals` plus those of its `pairs` (P, 2) partners, counting only pairs whose
    two normals are `known`, scaled to unit length."""
    sums = np.zeros(normals.shape)
    for side in range(2):
        for p in range(len(pairs)):
            a, b = pairs[p, side], pairs[p, 1 - side]
            if known[a] and known[b]:
                for c in range(3):
                    sums[a, c] += normals[b, c]
    for v in range(len(sums)):
        for c in range(3):
            sums[v, c] = normals[v, c] + sums[v, c]
        norm = np.sqrt(sums[v, 0] ** 2 + sums[v, 1] ** 2 + sums[v, 2] ** 2)
        norm = 1e-12 if norm < 1e-12 else norm
        for c in range(3):
            sums[v, c] /= norm
    return sums


@njit(**KERNEL)
def off_corners(
    normals: np.ndarray,
    tri: np.ndarray,
    face: np.ndarray,
    max_excess_deg: float,
    off: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.ring_faces._off_its_corners for faces [start:stop], into `off` (F,): whether a face's
    unit normal `face` (F, 3) lies further from one of its corners' `normals` (M, 3; corners `tri`
    (F, 3)) than the corners lie from each other, by more than `max_excess_deg`. The largest angle
    is the arccosine of the least cosine: two arccosines a face, not six."""
    for f in range(start, stop):
        to_face, apart = np.inf, np.inf
        for k in range(3):
            a, b = tri[f, k], tri[f, (k + 1) % 3]
            to_face = min(to_face, row_dot(normals, a, face, f))
            apart = min(apart, row_dot(normals, a, normals, b))
        bend = np.degrees(np.arccos(min(max(to_face, -1.0), 1.0)))
        spread = np.degrees(np.arccos(min(max(apart, -1.0), 1.0)))
        off[f] = bend - spread > max_excess_deg


@njit(**KERNEL)
def bent_from_corners(normals: np.ndarray, tri: np.ndarray, face: np.ndarray, least_cosine: float) -> np.ndarray:
    """(F,) whether a face's unit normal `face` (F, 3) lies further from one of its corners'
    `normals` (M, 3; corners `tri` (F, 3)) than the angle whose cosine is `least_cosine`."""
    bent = np.empty(len(face), np.bool_)
    for f in range(len(face)):
        bent[f] = False
        for k in range(3):
            a = tri[f, k]
            bent[f] = bent[f] or row_dot(normals, a, face, f) < least_cosine
    return bent


@njit(**KERNEL)
def pair_lengths(points: np.ndarray, xy: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far apart each pair (P, 2) of samples lies in space (`points` (M, 3), mm) and in the image
    (`xy` (M, 2), px): one pass, each length's squares summed in numpy's norm's order."""
    apart_mm, apart_px = np.empty(len(pairs)), np.empty(len(pairs))
    for n in range(len(pairs)):
        a, b = pairs[n, 0], pairs[n, 1]
        dx, dy, dz = points[a, 0] - points[b, 0], points[a, 1] - points[b, 1], points[a, 2] - points[b, 2]
        apart_mm[n] = np.sqrt(dx * dx + dy * dy + dz * dz)
        u, v = xy[a, 0] - xy[b, 0], xy[a, 1] - xy[b, 1]
        apart_px[n] = np.sqrt(u * u + v * v)
    return apart_mm, apart_px
