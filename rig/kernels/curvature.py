"""The surface curvature's per-point sums (rig.geometry.curvature), compiled by numba: each fit's
neighbours read in place from the voxel grid, their covariance and the quadric's normal equations
summed in registers. As numpy passes over (points, neighbours, 6) arrays these took two of the
three seconds of a ring plan's curvature (1 million points, line profile, scratch)."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL

_TERMS = 6  # x^2, xy, y^2, x, y, 1


@njit(**KERNEL)
def neighbour_spread(
    grid: np.ndarray,
    centres: np.ndarray,
    index: np.ndarray,
    inside: np.ndarray,
    mean: np.ndarray,
    cov: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """For centres [start, stop): the mean `mean` (M, 3) of their neighbours' offsets (grid[index]
    - centre where `inside`, (M, K)) and the covariance sums `cov` (M, 3, 3) about it, leaving out a
    neighbour at the centre itself (offset 0: it would pull the least-spread direction nowhere)."""
    for m in range(start, stop):
        count = 0
        s0 = s1 = s2 = 0.0
        for k in range(index.shape[1]):
            if inside[m, k]:
                count += 1
                p = index[m, k]
                s0 += grid[p, 0] - centres[m, 0]
                s1 += grid[p, 1] - centres[m, 1]
                s2 += grid[p, 2] - centres[m, 2]
        count = max(count, 1)
        mean[m, 0], mean[m, 1], mean[m, 2] = s0 / count, s1 / count, s2 / count
        cov[m, :, :] = 0.0
        for k in range(index.shape[1]):
            if not inside[m, k]:
                continue
            p = index[m, k]
            l0, l1, l2 = grid[p, 0] - centres[m, 0], grid[p, 1] - centres[m, 1], grid[p, 2] - centres[m, 2]
            if l0 == 0.0 and l1 == 0.0 and l2 == 0.0:
                continue
            d0, d1, d2 = l0 - mean[m, 0], l1 - mean[m, 1], l2 - mean[m, 2]
            cov[m, 0, 0] += d0 * d0
            cov[m, 0, 1] += d0 * d1
            cov[m, 0, 2] += d0 * d2
            cov[m, 1, 1] += d1 * d1
            cov[m, 1, 2] += d1 * d2
            cov[m, 2, 2] += d2 * d2
        cov[m, 1, 0], cov[m, 2, 0], cov[m, 2, 1] = cov[m, 0, 1], cov[m, 0, 2], cov[m, 1, 2]


@njit(**KERNEL)
def quadric_sums(
    grid: np.ndarray,
    centres: np.ndarray,
    index: np.ndarray,
    inside: np.ndarray,
    frames: np.ndarray,
    gram: np.ndarray,
    right: np.ndarray,
    along: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """For centres [start, stop): the normal equations of z = a x^2 + b xy + c y^2 + d x + e y + f
    over their neighbours in each one's frame (`frames` (M, 3, 3): rows e1, e2, normal), `gram`
    (M, 6, 6) and `right` (M, 6), and the sums of the neighbours' x and y (`along` (M, 2))."""
    row = np.empty(_TERMS)
    for m in range(start, stop):
        gram[m, :, :] = 0.0
        right[m, :] = 0.0
        sx = sy = 0.0
        for k in range(index.shape[1]):
            if not inside[m, k]:
                continue
            x, y, z = _in_frame(grid, centres, frames, m, index[m, k])
            sx += x
            sy += y
            row[0], row[1], row[2], row[3], row[4], row[5] = x * x, x * y, y * y, x, y, 1.0
            for a in range(_TERMS):
                right[m, a] += row[a] * z
                for b in range(a, _TERMS):
                    gram[m, a, b] += row[a] * row[b]
        for a in range(_TERMS):
            for b in range(a):
                gram[m, a, b] = gram[m, b, a]
        along[m, 0], along[m, 1] = sx, sy


@njit(**KERNEL)
def quadric_misfits(
    grid: np.ndarray,
    centres: np.ndarray,
    index: np.ndarray,
    inside: np.ndarray,
    frames: np.ndarray,
    coef: np.ndarray,
    squares: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """For centres [start, stop): the sum of squares `squares` (M,) of their neighbours' heights off
    the fitted quadric `coef` (M, 6)."""
    for m in range(start, stop):
        total = 0.0
        for k in range(index.shape[1]):
            if not inside[m, k]:
                continue
            x, y, z = _in_frame(grid, centres, frames, m, index[m, k])
            c = coef[m]
            height = c[0] * x * x + c[1] * x * y + c[2] * y * y + c[3] * x + c[4] * y + c[5]
            total += (height - z) ** 2
        squares[m] = total


@njit(nogil=True, cache=True, inline="always")
def _in_frame(grid: np.ndarray, centres: np.ndarray, frames: np.ndarray, m: int, p: int) -> tuple[float, float, float]:
    """Grid point p's offset from centre m in that centre's frame (e1, e2, normal)."""
    l0, l1, l2 = grid[p, 0] - centres[m, 0], grid[p, 1] - centres[m, 1], grid[p, 2] - centres[m, 2]
    f = frames[m]
    return (
        l0 * f[0, 0] + l1 * f[0, 1] + l2 * f[0, 2],
        l0 * f[1, 0] + l1 * f[1, 1] + l2 * f[1, 2],
        l0 * f[2, 0] + l1 * f[2, 1] + l2 * f[2, 2],
    )
