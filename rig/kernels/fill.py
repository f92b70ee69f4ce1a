"""The surface fill's per-pixel fit (rig.pipeline.fill), compiled by numba.

Each pixel's quadratic height field is a 6x6 weighted least-squares problem over its few dozen
sample rows. As numpy passes over (pixels, rows, 6) arrays it took 0.5 s for the default bench's
ring scan (line profile, scratch); one loop per pixel keeps each problem in registers. Like
rig.kernels.dense, the loop releases the GIL and takes a span of pixels [start, stop) for rig.workers'
pool, and is compiled on first use and cached beside this file.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL

_TERMS = 6  # 1, x, y, x^2, xy, y^2


@njit(**KERNEL)
def fit_height_fields(
    points: np.ndarray,
    normals: np.ndarray,
    index: np.ndarray,
    use: np.ndarray,
    ridge: float,
    coef: np.ndarray,
    frame: np.ndarray,
    origin: np.ndarray,
    misfit: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """For pixels [start, stop): the weighted quadratic height field of its used samples (`index`,
    `use`: (N, k)), in a frame along their mean normal with x and y in units of the neighbourhood's
    size: its coefficients `coef` (N, 6), the frame's rows scaled back to millimetres `frame`
    (N, 3, 3), its `origin` (N, 3) and the rms of the samples' heights off it `misfit` (N,).
    Heights count once per sample, slopes (where the normal is not steeper than 0.2 off the
    plane) twice; `ridge` (times the weight) holds the bends toward zero. NaN where it is singular."""
    k = index.shape[1]
    for n in range(start, stop):
        weight = 0.0
        o, up = np.zeros(3), np.zeros(3)
        for j in range(k):
            if use[n, j]:
                weight += 1.0
                for c in range(3):
                    o[c] += points[index[n, j], c]
                    up[c] += normals[index[n, j], c]
        o /= weight
        axes = _axes(up / np.sqrt(np.sum(up**2)))
        local, slope = np.zeros((k, 3)), np.zeros((k, 3))
        spread = 0.0
        for j in range(k):
            if use[n, j]:
                s = index[n, j]
                for a in range(3):  # by hand: numba's @ allocates
                    for c in range(3):
                        local[j, a] += axes[a, c] * (points[s, c] - o[c])
                        slope[j, a] += axes[a, c] * normals[s, c]
                spread += local[j, 0] ** 2 + local[j, 1] ** 2
        scale = np.sqrt(spread / weight) + 1e-6
        coef[n] = _fit(local, slope, use[n], scale, ridge * weight)
        squares = 0.0
        for j in range(k):
            if use[n, j]:
                squares += (_height(coef[n], local[j, 0] / scale, local[j, 1] / scale) - local[j, 2]) ** 2
        misfit[n] = np.sqrt(squares / weight)
        frame[n, :2] = axes[:2] / scale
        frame[n, 2] = axes[2]
        origin[n] = o


@njit(**KERNEL)
def _axes(up: np.ndarray) -> np.ndarray:
    """Rows e1, e2, up: a right-handed frame about the unit normal `up`."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(up, ref)
    e1 /= np.sqrt(np.sum(e1**2))
    axes = np.empty((3, 3))
    axes[0], axes[1], axes[2] = e1, np.cross(up, e1), up
    return axes


@njit(**KERNEL)
def _fit(local: np.ndarray, slope: np.ndarray, use: np.ndarray, scale: float, ridge: float) -> np.ndarray:
    """The height field's six coefficients from the used samples' local positions and normals."""
    normal, right, row = np.zeros((_TERMS, _TERMS)), np.zeros(_TERMS), np.zeros(_TERMS)
    for j in range(len(use)):
        if not use[j]:
            continue
        x, y = local[j, 0] / scale, local[j, 1] / scale
        row[0], row[1], row[2], row[3], row[4], row[5] = 1.0, x, y, x * x, x * y, y * y
        _accumulate(normal, right, row, local[j, 2])
        nz = slope[j, 2]
        if abs(nz) > 0.2:
            row[0], row[1], row[2], row[3], row[4], row[5] = 0.0, 1.0, 0.0, 2 * x, y, 0.0
            _accumulate(normal, right, row, -slope[j, 0] / nz * scale)
            row[0], row[1], row[2], row[3], row[4], row[5] = 0.0, 0.0, 1.0, 0.0, x, 2 * y
            _accumulate(normal, right, row, -slope[j, 1] / nz * scale)
    for t in range(3, _TERMS):
        normal[t, t] += ridge
    return _solve(normal, right)


@njit(**KERNEL)
def _height(c: np.ndarray, x: float, y: float) -> float:
    return c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y


@njit(**KERNEL)
def _accumulate(normal: np.ndarray, right: np.ndarray, row: np.ndarray, target: float) -> None:
    for a in range(_TERMS):
        right[a] += row[a] * target
        for b in range(_TERMS):
            normal[a, b] += row[a] * row[b]


@njit(**KERNEL)
def _solve(matrix: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Gaussian elimination with partial pivoting (both arguments are overwritten); NaN if singular."""
    size = len(right)
    for col in range(size):
        pivot = col
        for r in range(col + 1, size):
            if abs(matrix[r, col]) > abs(matrix[pivot, col]):
                pivot = r
        if abs(matrix[pivot, col]) < 1e-300:
            return np.full(size, np.nan)
        if pivot != col:
            for c in range(size):
                matrix[col, c], matrix[pivot, c] = matrix[pivot, c], matrix[col, c]
            right[col], right[pivot] = right[pivot], right[col]
        for r in range(col + 1, size):
            factor = matrix[r, col] / matrix[col, col]
            for c in range(col, size):
                matrix[r, c] -= factor * matrix[col, c]
            right[r] -= factor * right[col]
    out = np.zeros(size)
    for r in range(size - 1, -1, -1):
        total = right[r]
        for c in range(r + 1, size):
            total -= matrix[r, c] * out[c]
        out[r] = total / matrix[r, r]
    return out
