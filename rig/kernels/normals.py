"""The ring samples' normals (rig.pipeline.normals) and the ring triangles' bend test
(rig.pipeline.surface), compiled by numba: sums over faces and pairs in one loop each, in numpy's
bincount order (every face's corner 0, then 1, then 2), so the sums are numpy's to the last bit.
As numpy passes they took a fifth of the ring surface's triangles (scratch profile, default bench).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(**KERNEL)
def corner_sums(tri: np.ndarray, vectors: np.ndarray, sums: np.ndarray) -> None:
    """Add each face's `vectors` row (F, 3) to the `sums` row (M, 3) of each of its corners `tri` (F, 3)."""
    for k in range(3):
        for f in range(len(tri)):
            v = tri[f, k]
            for c in range(3):
                sums[v, c] += vectors[f, c]


@njit(**KERNEL)
def pair_sums(normals: np.ndarray, pairs: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(M, 3) per sample, the sum of the `normals` of its `pairs` (P, 2) partners, counting only
    pairs whose two normals are `known`."""
    sums = np.zeros(normals.shape)
    for side in range(2):
        for p in range(len(pairs)):
            a, b = pairs[p, side], pairs[p, 1 - side]
            if known[a] and known[b]:
                for c in range(3):
                    sums[a, c] += normals[b, c]
    return sums


@njit(**KERNEL)
def off_corners(corners: np.ndarray, face: np.ndarray, max_excess_deg: float) -> np.ndarray:
    """(F,) rig.pipeline.surface._off_its_corners: whether a face's unit normal `face` (F, 3) lies
    further from one of its corners' normals `corners` (F, 3, 3) than the corners lie from each
    other, by more than `max_excess_deg`."""
    off = np.empty(len(face), np.bool_)
    for f in range(len(face)):
        bend, spread = -np.inf, -np.inf
        for k in range(3):
            n = (k + 1) % 3
            to_face = corners[f, k, 0] * face[f, 0] + corners[f, k, 1] * face[f, 1] + corners[f, k, 2] * face[f, 2]
            apart = (
                corners[f, k, 0] * corners[f, n, 0]
                + corners[f, k, 1] * corners[f, n, 1]
                + corners[f, k, 2] * corners[f, n, 2]
            )
            bend = max(bend, np.degrees(np.arccos(min(max(to_face, -1.0), 1.0))))
            spread = max(spread, np.degrees(np.arccos(min(max(apart, -1.0), 1.0))))
        off[f] = bend - spread > max_excess_deg
    return off
