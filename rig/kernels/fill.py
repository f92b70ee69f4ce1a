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
from rig.kernels.cells import Cells

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
    normal, right, row = np.empty((_TERMS, _TERMS)), np.empty(_TERMS), np.empty(_TERMS)
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
        local[:], slope[:] = 0.0, 0.0
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
        _fit(local, slope, use[n], (scale, ridge * weight), (normal, right, row), coef[n])
        squares = 0.0
        for j in range(k):
            if use[n, j]:
                squares += (_height(coef[n], local[j, 0] / scale, local[j, 1] / scale) - local[j, 2]) ** 2
        misfit[n] = np.sqrt(squares / weight)
        for c in range(3):
            frame[n, 0, c], frame[n, 1, c], frame[n, 2, c] = axes[0, c] / scale, axes[1, c] / scale, axes[2, c]
            origin[n, c] = o[c]


@njit(nogil=True, cache=True)
def _axes(up: np.ndarray, axes: np.ndarray) -> None:
    """Rows e1, e2, up of `axes`: a right-handed frame about the unit normal `up`."""
    rx, ry, rz = (1.0, 0.0, 0.0) if abs(up[0]) < 0.9 else (0.0, 1.0, 0.0)
    ex, ey, ez = up[1] * rz - up[2] * ry, up[2] * rx - up[0] * rz, up[0] * ry - up[1] * rx
    size = np.sqrt(ex**2 + ey**2 + ez**2)
    ex, ey, ez = ex / size, ey / size, ez / size
    axes[0, 0], axes[0, 1], axes[0, 2] = ex, ey, ez
    axes[1, 0], axes[1, 1], axes[1, 2] = up[1] * ez - up[2] * ey, up[2] * ex - up[0] * ez, up[0] * ey - up[1] * ex
    axes[2, 0], axes[2, 1], axes[2, 2] = up[0], up[1], up[2]


@njit(nogil=True, cache=True)
def _fit(
    local: np.ndarray,
    slope: np.ndarray,
    use: np.ndarray,
    scales: tuple[float, float],
    scratch: tuple[np.ndarray, np.ndarray, np.ndarray],
    coef: np.ndarray,
) -> None:
    """The height field's six coefficients `coef` from the used samples' local positions and
    normals; scales: (the neighbourhood's size, the ridge)."""
    scale, ridge = scales
    normal, right, row = scratch
    normal[:], right[:] = 0.0, 0.0
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
    for a in range(_TERMS):
        for b in range(a):
            normal[a, b] = normal[b, a]
    for t in range(3, _TERMS):
        normal[t, t] += ridge
    _solve(normal, right, coef)


@njit(**KERNEL)
def _height(c: np.ndarray, x: float, y: float) -> float:
    return c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y


@njit(**KERNEL)
def _accumulate(normal: np.ndarray, right: np.ndarray, row: np.ndarray, target: float) -> None:
    """Add a row of the least-squares system to its normal equations: their upper triangle only
    (the lower is the same products, mirrored once all rows are in)."""
    for a in range(_TERMS):
        if row[a] != 0.0:  # a slope's row is half zeros; adding their products adds nothing
            right[a] += row[a] * target
            for b in range(a, _TERMS):
                normal[a, b] += row[a] * row[b]


@njit(**KERNEL)
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
                apart_mm = np.sqrt(
                    (points[s, 0] - points[ref, 0]) ** 2
                    + (points[s, 1] - points[ref, 1]) ** 2
                    + (points[s, 2] - points[ref, 2]) ** 2
                )
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


@njit(nogil=True, cache=True, inline="always")
def _insert(dist: np.ndarray, index: np.ndarray, size: int, found: int, d: float, sample: int) -> int:
    """Put (d, sample) into the first `size` slots of the sorted (dist, index) holding `found`."""
    if size == 0 or (found == size and d >= dist[size - 1]):
        return found
    slot = min(found, size - 1)
    while slot > 0 and dist[slot - 1] > d:
        dist[slot], index[slot] = dist[slot - 1], index[slot - 1]
        slot -= 1
    dist[slot], index[slot] = d, sample
    return min(found + 1, size)


@njit(**KERNEL)
def ring_presence(xy: np.ndarray, ring: np.ndarray, cells: Cells, cell: float, rings: int) -> np.ndarray:
    """(cells, words) uint64: which of `rings` rings (bit r % 64 of word r // 64) have a sample in
    each of the `cells` (side `cell`) of samples `xy`."""
    _, _, x0, y0, nx, ny = cells
    presence = np.zeros((nx * ny, (rings + 63) // 64), np.uint64)
    for s in range(len(xy)):
        c = int((xy[s, 1] - y0) / cell) * nx + int((xy[s, 0] - x0) / cell)
        presence[c, ring[s] // 64] |= np.uint64(1) << np.uint64(ring[s] % 64)
    return presence


@njit(nogil=True, cache=True)
def _both_present(
    presence: np.ndarray, cells: Cells, lengths: tuple[float, float], at: np.ndarray, rings: tuple[int, int]
) -> bool:
    """Whether a cell within `reach` of `at` (a square of cells about it: it may overstate, never
    miss) holds a sample of rings[0], and one holds a sample of rings[1] (or rings[1] is -1).
    lengths: (reach, cell)."""
    _, _, x0, y0, nx, ny = cells
    reach, cell = lengths
    lo_x = min(max(int((at[0] - reach - x0) // cell), 0), nx - 1)
    hi_x = min(max(int((at[0] + reach - x0) // cell), 0), nx - 1)
    lo_y = min(max(int((at[1] - reach - y0) // cell), 0), ny - 1)
    hi_y = min(max(int((at[1] + reach - y0) // cell), 0), ny - 1)
    seen_first, seen_second = False, rings[1] < 0
    for gy in range(lo_y, hi_y + 1):
        for gx in range(lo_x, hi_x + 1):
            c = gy * nx + gx
            seen_first = seen_first or _has(presence, c, rings[0])
            seen_second = seen_second or _has(presence, c, rings[1])
            if seen_first and seen_second:
                return True
    return False


@njit(nogil=True, cache=True, inline="always")
def _has(presence: np.ndarray, c: int, r: int) -> bool:
    return r >= 0 and (presence[c, r // 64] >> np.uint64(r % 64)) & np.uint64(1) != 0


@njit(**KERNEL)
def fill_neighbourhoods(
    xy: np.ndarray,
    ring: np.ndarray,
    members: np.ndarray,
    cells: Cells,
    presence: np.ndarray,
    at: np.ndarray,
    annulus: np.ndarray,
    sizes: tuple[int, float, float],
    dist: np.ndarray,
    index: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.fill._neighbourhoods for pixels at[start:stop] (their annulus a: rings a - 1 and
    a, or ring 0 inside it): the `k` nearest samples within `reach` of any ring, then the k / 2
    nearest of each of its two rings (k of ring 0 alone; at most `members[r]`) not among those.
    dist inf (index 0) for an empty slot, and everywhere for a pixel whose rings do not both reach
    it (or do not exist). sizes: (k, reach, cell); cells: rig.kernels.cells.sample_cells of that side,
    presence: ring_presence in them."""
    k = sizes[0]
    for i in range(start, stop):
        dist[i, :] = np.inf
        index[i, :] = 0
        a = annulus[i]
        first, second = (0, -1) if a == 0 else (a - 1, a)
        if first >= len(members) or second >= len(members) or members[first] == 0:
            continue
        if second >= 0 and members[second] == 0:
            continue
        if not _both_present(presence, cells, sizes[1:], at[i], (first, second)):
            continue  # most pixels beyond a surface's last ring: their outer ring is nowhere near
        near = min(k, len(xy))
        n_first = min(near if second < 0 else near // 2, members[first])
        wanted = (near, n_first, 0 if second < 0 else min(near // 2, members[second]))
        found = _search(xy, ring, cells, sizes[1:], at[i], (first, second), wanted, dist[i], index[i])
        if found[1] == 0 or (second >= 0 and found[2] == 0):
            dist[i, :] = np.inf
            index[i, :] = 0
            continue
        for j in range(near, near + wanted[1] + wanted[2]):  # listed already among the nearest of any ring
            for m in range(found[0]):
                if index[i, m] == index[i, j] and np.isfinite(dist[i, j]):
                    dist[i, j] = np.inf
        for j in range(dist.shape[1]):
            if not np.isfinite(dist[i, j]):
                index[i, j] = 0


@njit(nogil=True, cache=True)
def _search(
    xy: np.ndarray,
    ring: np.ndarray,
    cells: Cells,
    lengths: tuple[float, float],
    at: np.ndarray,
    rings: tuple[int, int],
    wanted: tuple[int, int, int],
    row_d: np.ndarray,
    row_i: np.ndarray,
) -> tuple[int, int, int]:
    """One pixel's three lists (nearest of any ring, of rings[0], of rings[1]; `wanted` long each,
    laid end to end in row_d and row_i), searched ring of cells by ring of cells about the pixel's
    until no cell left can hold a nearer sample; how many each found. lengths: (reach, cell)."""
    order, starts, x0, y0, nx, ny = cells
    reach, cell = lengths
    near, n_first, n_second = wanted
    tail = near + n_first
    found = found_first = found_second = 0
    px, py = at[0], at[1]
    cx = min(max(int((px - x0) // cell), 0), nx - 1)
    cy = min(max(int((py - y0) // cell), 0), ny - 1)
    for step in range(int(reach // cell) + 2):
        for gy in range(max(cy - step, 0), min(cy + step, ny - 1) + 1):
            edge = gy == cy - step or gy == cy + step
            for gx in range(max(cx - step, 0), min(cx + step, nx - 1) + 1):
                if not edge and cx - step < gx < cx + step:
                    continue
                c = gy * nx + gx
                for j in range(starts[c], starts[c + 1]):
                    s = order[j]
                    d = np.sqrt((xy[s, 0] - px) ** 2 + (xy[s, 1] - py) ** 2)
                    if d >= reach:
                        continue
                    found = _insert(row_d, row_i, near, found, d, s)
                    if ring[s] == rings[0]:
                        found_first = _insert(row_d[near:], row_i[near:], n_first, found_first, d, s)
                    elif ring[s] == rings[1]:
                        found_second = _insert(row_d[tail:], row_i[tail:], n_second, found_second, d, s)
        # every sample nearer than the searched block's nearest outside edge has been seen
        inner = min(
            px - (x0 + (cx - step) * cell), x0 + (cx + step + 1) * cell - px,
            py - (y0 + (cy - step) * cell), y0 + (cy + step + 1) * cell - py,
        )  # fmt: skip
        if inner >= reach:
            break
        done = found == near and row_d[near - 1] <= inner
        done = done and found_first == n_first and (n_first == 0 or row_d[near + n_first - 1] <= inner)
        if done and found_second == n_second and (n_second == 0 or row_d[tail + n_second - 1] <= inner):
            break
    return found, found_first, found_second
