"""The surface fill's per-pixel fit (rig.pipeline.fill), compiled by numba.

Each pixel's quadratic height field is a 6x6 weighted least-squares problem over its few dozen
sample rows. As numpy passes over (pixels, rows, 6) arrays it took 0.5 s for the default bench's
ring scan (line profile, scratch); one loop per pixel keeps each problem in registers. Like
rig.kernels.dense, the loop releases the GIL and takes a span of pixels [start, stop) for rig.workers'
pool, and is compiled on first use and cached beside this file. The fit's helpers are inlined
into it (numba's inline="always"): called, with the arrays they write as arguments, they took a
third of its time (43 against 29 ms on one thread for the default bench's 22,000 fits). A row of
the normal equations is a tuple, whose zeros inlining makes constants, and each used sample's local
position is written once, not zeroed and added to (29 -> 22.5 ms).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL
from rig.kernels.cells import Cells, nearest_within
from rig.kernels.vectors import row_distance

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
    o, up, axes = np.empty(3), np.empty(3), np.empty((3, 3))  # scratch: one pixel's, reused
    local, slope = np.empty((k, 3)), np.empty((k, 3))
    normal, right = np.empty((_TERMS, _TERMS)), np.empty(_TERMS)
    for n in range(start, stop):
        weight = 0.0
        o[:], up[:] = 0.0, 0.0
        for j in range(k):
            if use[n, j]:
                weight += 1.0
                for c in range(3):
                    o[c] += points[index[n, j], c]
                    up[c] += normals[index[n, j], c]
        o /= weight
        up /= np.sqrt(up[0] ** 2 + up[1] ** 2 + up[2] ** 2)
        _axes(up, axes)
        spread = 0.0
        for j in range(k):
            if use[n, j]:  # only the used rows are read: the others are left as they were
                s = index[n, j]
                for a in range(3):  # by hand: numba's @ allocates
                    at, turned = 0.0, 0.0
                    for c in range(3):
                        at += axes[a, c] * (points[s, c] - o[c])
                        turned += axes[a, c] * normals[s, c]
                    local[j, a], slope[j, a] = at, turned
                spread += local[j, 0] ** 2 + local[j, 1] ** 2
        scale = np.sqrt(spread / weight) + 1e-6
        fitted = coef[n]
        _fit(local, slope, use[n], (scale, ridge * weight), (normal, right), fitted)
        squares = 0.0
        for j in range(k):
            if use[n, j]:
                squares += (_height(fitted, local[j, 0] / scale, local[j, 1] / scale) - local[j, 2]) ** 2
        misfit[n] = np.sqrt(squares / weight)
        for c in range(3):
            frame[n, 0, c], frame[n, 1, c], frame[n, 2, c] = axes[0, c] / scale, axes[1, c] / scale, axes[2, c]
            origin[n, c] = o[c]


@njit(nogil=True, cache=True, inline="always")
def _axes(up: np.ndarray, axes: np.ndarray) -> None:
    """Rows e1, e2, up of `axes`: a right-handed frame about the unit normal `up`."""
    rx, ry, rz = (1.0, 0.0, 0.0) if abs(up[0]) < 0.9 else (0.0, 1.0, 0.0)
    ex, ey, ez = up[1] * rz - up[2] * ry, up[2] * rx - up[0] * rz, up[0] * ry - up[1] * rx
    size = np.sqrt(ex**2 + ey**2 + ez**2)
    ex, ey, ez = ex / size, ey / size, ez / size
    axes[0, 0], axes[0, 1], axes[0, 2] = ex, ey, ez
    axes[1, 0], axes[1, 1], axes[1, 2] = up[1] * ez - up[2] * ey, up[2] * ex - up[0] * ez, up[0] * ey - up[1] * ex
    axes[2, 0], axes[2, 1], axes[2, 2] = up[0], up[1], up[2]


@njit(nogil=True, cache=True, inline="always")
def _fit(
    local: np.ndarray,
    slope: np.ndarray,
    use: np.ndarray,
    scales: tuple[float, float],
    scratch: tuple[np.ndarray, np.ndarray],
    coef: np.ndarray,
) -> None:
    """The height field's six coefficients `coef` from the used samples' local positions and
    normals; scales: (the neighbourhood's size, the ridge)."""
    scale, ridge = scales
    normal, right = scratch
    normal[:], right[:] = 0.0, 0.0
    for j in range(len(use)):
        if not use[j]:
            continue
        x, y = local[j, 0] / scale, local[j, 1] / scale
        _accumulate(normal, right, (1.0, x, y, x * x, x * y, y * y), local[j, 2])
        nz = slope[j, 2]
        if abs(nz) > 0.2:
            _accumulate(normal, right, (0.0, 1.0, 0.0, 2 * x, y, 0.0), -slope[j, 0] / nz * scale)
            _accumulate(normal, right, (0.0, 0.0, 1.0, 0.0, x, 2 * y), -slope[j, 1] / nz * scale)
    for a in range(_TERMS):
        for b in range(a):
            normal[a, b] = normal[b, a]
    for t in range(3, _TERMS):
        normal[t, t] += ridge
    _solve(normal, right, coef)


@njit(nogil=True, cache=True, inline="always")
def _height(c: np.ndarray, x: float, y: float) -> float:
    return c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y


@njit(nogil=True, cache=True, inline="always")
def _accumulate(normal: np.ndarray, right: np.ndarray, row: tuple[float, ...], target: float) -> None:
    """Add a row of the least-squares system to its normal equations: their upper triangle only
    (the lower is the same products, mirrored once all rows are in). The row is a tuple: inlined,
    a slope's zeros are constants and their products are never made."""
    for a in range(_TERMS):
        if row[a] != 0.0:  # a slope's row is half zeros; adding their products adds nothing
            right[a] += row[a] * target
            for b in range(a, _TERMS):
                normal[a, b] += row[a] * row[b]


@njit(nogil=True, cache=True, inline="always")
def _solve(matrix: np.ndarray, right: np.ndarray, out: np.ndarray) -> None:
    """Gaussian elimination with partial pivoting into `out` (both arguments are overwritten); NaN
    if singular."""
    size = len(right)
    for col in range(size):
        pivot = col
        for r in range(col + 1, size):
            if abs(matrix[r, col]) > abs(matrix[pivot, col]):
                pivot = r
        if abs(matrix[pivot, col]) < 1e-300:
            out[:] = np.nan
            return
        if pivot != col:
            for c in range(size):
                matrix[col, c], matrix[pivot, c] = matrix[pivot, c], matrix[col, c]
            right[col], right[pivot] = right[pivot], right[col]
        for r in range(col + 1, size):
            factor = matrix[r, col] / matrix[col, col]
            for c in range(col, size):
                matrix[r, c] -= factor * matrix[col, c]
            right[r] -= factor * right[col]
    out[:] = 0.0
    for r in range(size - 1, -1, -1):
        total = right[r]
        for c in range(r + 1, size):
            total -= matrix[r, c] * out[c]
        out[r] = total / matrix[r, r]


@njit(**KERNEL)
def one_surface(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    footprint: np.ndarray,
    neighbourhood: tuple[np.ndarray, np.ndarray],
    annulus: np.ndarray,
    stretch: float,
    use: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.fill._one_surface for pixels [start, stop): `use` (N, k) marks the samples of a
    pixel's two rings (annulus a: rings a - 1 and a) on the surface of the nearest of them, none
    where a sample in reach of any ring lies apart from that one by more than `stretch` times its
    `footprint` (mm per pixel, per sample) per pixel of image plus one, and none where the used
    samples are not of both rings (but inside ring 0). neighbourhood: (dist, index) (N, k), dist
    inf for an empty slot (fill_neighbourhoods)."""
    dist, index = neighbourhood
    k = index.shape[1]
    for n in range(start, stop):
        use[n, :] = False
        a = annulus[n]
        first, best = -1, np.inf
        for j in range(k):
            r = ring[index[n, j]]
            if dist[n, j] < best and (r == a or r == a - 1):
                first, best = j, dist[n, j]
        if first < 0:
            continue
        ref = index[n, first]
        contested = False
        for j in range(k):
            if np.isfinite(dist[n, j]):
                s = index[n, j]
                apart_px = np.sqrt((xy[s, 0] - xy[ref, 0]) ** 2 + (xy[s, 1] - xy[ref, 1]) ** 2)
                apart_mm = row_distance(points, ref, s)
                contested = contested or not apart_mm <= stretch * footprint[ref] * (apart_px + 1.0)
        if contested:
            continue
        inner = outer = False
        for j in range(k):
            r = ring[index[n, j]]
            use[n, j] = np.isfinite(dist[n, j]) and (r == a or r == a - 1)
            inner = inner or (use[n, j] and r == a - 1)
            outer = outer or (use[n, j] and r == a)
        if a != 0 and not (inner and outer):
            use[n, :] = False


@njit(**KERNEL)
def fill_neighbourhoods(
    members: np.ndarray,
    cells: tuple[Cells, Cells],
    ring_of: np.ndarray,
    at: np.ndarray,
    annulus: np.ndarray,
    sizes: tuple[int, float, float, float],
    dist: np.ndarray,
    index: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.fill._neighbourhoods for pixels at[start:stop] (their annulus a: rings a - 1 and
    a, or ring 0 inside it): the `k` nearest samples within `reach` of any ring, then the k / 2
    nearest of each of its two rings (k of ring 0 alone; at most `members[r]`) not among those.
    dist inf (index 0) for an empty slot, and everywhere for a pixel whose rings do not both reach
    it (or do not exist). cells: rig.kernels.cells.sample_cells of the samples and group_cells of
    them by ring; ring_of: each sample's ring; sizes: (k, reach, the cells' side, the ring cells'
    side). A ring is searched in its own cells only where the nearest of any ring hold fewer of it
    than its share: where they hold as many, its nearest are all among them (save a tie in distance
    at the last of them) and would only be struck off the list again."""
    k, reach, cell, ring_cell = sizes
    for i in range(start, stop):
        dist[i, :] = np.inf
        index[i, :] = 0
        a = annulus[i]
        first, second = (0, -1) if a == 0 else (a - 1, a)
        if first >= len(members) or second >= len(members) or members[first] == 0:
            continue
        if second >= 0 and members[second] == 0:
            continue
        near = min(k, len(cells[0][0]))
        n_first = min(near if second < 0 else near // 2, members[first])
        n_second = 0 if second < 0 else min(near // 2, members[second])
        point = (at[i, 0], at[i, 1])
        found = nearest_within(cells[0], (cell, 0, reach), point, dist[i, :near], index[i, :near])
        held_first = held_second = 0
        for m in range(found):
            held_first += ring_of[index[i, m]] == first
            held_second += ring_of[index[i, m]] == second
        tail, end = near + n_first, near + n_first + n_second
        where_first, where_second = (ring_cell, first, reach), (ring_cell, second, reach)
        if (
            held_first < n_first
            and nearest_within(cells[1], where_first, point, dist[i, near:tail], index[i, near:tail]) == 0
        ) or (
            held_second < n_second
            and nearest_within(cells[1], where_second, point, dist[i, tail:end], index[i, tail:end]) == 0
        ):  # a ring that does not reach the pixel: no neighbourhood
            dist[i, :] = np.inf
            index[i, :] = 0
            continue
        for j in range(near, end):  # listed already among the nearest of any ring
            for m in range(found):
                if index[i, m] == index[i, j] and np.isfinite(dist[i, j]):
                    dist[i, j] = np.inf
        for j in range(dist.shape[1]):
            if not np.isfinite(dist[i, j]):
                index[i, j] = 0


@njit(**KERNEL)
def reached(
    pixel: np.ndarray, annulus: np.ndarray, grid: tuple[int, float, float, float], near: np.ndarray, out: np.ndarray
) -> None:
    """rig.pipeline.fill._rings_reach's look for each flat pixel `pixel` (N,) of annulus `annulus`
    (N,): out (N,) whether `near` (rings, cells down, cells across: a sample of that ring
    within a box of cells) holds at its cell for ring a - 1 and ring a (ring 0 alone for a = 0).
    grid: (the image's width, the cells' corner x and y, their side)."""
    width, x0, y0, cell = grid
    for i in range(len(pixel)):
        a = annulus[i]
        cx, cy = int((pixel[i] % width - x0) // cell), int((pixel[i] // width - y0) // cell)
        out[i] = a >= 0 and near[max(a - 1, 0), cy, cx] and (a == 0 or near[a, cy, cx])
