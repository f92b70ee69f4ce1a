"""Three-vectors held as rows of (N, 3) arrays, for the compiled loops: each helper reads the rows
it needs in place (no (3,) views or temporaries per call) and is inlined where it is used."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True, inline="always")
def corner_cross(points: np.ndarray, a: int, b: int, c: int) -> tuple[float, float, float]:
    """(points[b] - points[a]) x (points[c] - points[a]): a triangle's normal, twice its area long."""
    ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
    vx, vy, vz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
    return uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


@njit(nogil=True, cache=True, inline="always")
def row_dot(u: np.ndarray, i: int, v: np.ndarray, j: int) -> float:
    """u[i] . v[j]."""
    return u[i, 0] * v[j, 0] + u[i, 1] * v[j, 1] + u[i, 2] * v[j, 2]


@njit(nogil=True, cache=True, inline="always")
def row_distance(points: np.ndarray, i: int, j: int) -> float:
    """|points[j] - points[i]|."""
    return np.sqrt(
        (points[j, 0] - points[i, 0]) ** 2 + (points[j, 1] - points[i, 1]) ** 2 + (points[j, 2] - points[i, 2]) ** 2
    )
