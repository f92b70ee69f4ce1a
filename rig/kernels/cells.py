"""Image points sorted into a grid of square cells (a counting sort), all together or a group (a
ring) at a time, and the neighbour searches over them, compiled by numba: the ring codec's searches
(rig.kernels.fill, rig.kernels.rings, rig.pipeline.normals, rig.pipeline.ring_triangulation) scan
a point's few cells instead of a k-d tree, and stop when no cell left can hold a nearer point."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL, bounds

# order (the points' indices cell by cell), starts (where each cell's run starts, cells + 1),
# the grid's corner x0, y0, its size in cells nx, ny, and the points (M, 2) in the cells' order (a
# cell's points side by side in memory, for the searches)
Cells = tuple[np.ndarray, np.ndarray, float, float, int, int, np.ndarray]


@njit(**KERNEL)
def sample_cells(xy: np.ndarray, cell: float) -> Cells:
    """The samples `xy` (M, 2) sorted into square cells of side `cell`: their indices cell by cell,
    where each cell's run starts ((cells + 1,)), the grid's corner, its size in cells and the
    samples in the cells' order."""
    return group_cells(xy, np.zeros(len(xy), np.int64), 1, cell)


def group_cell_side(xy: np.ndarray, groups: int, smallest: float, max_cells: int = 1_000_000) -> float:
    """The side of group_cells' cells for points `xy` in `groups` groups: `smallest`, or wider where
    groups x cells would pass `max_cells` (8 bytes of run starts each, and as many again to fill)."""
    if not len(xy):
        return float(smallest)
    lo, hi = bounds(xy)
    area = float(np.prod(hi - lo + 1.0))
    return max(float(smallest), float(np.sqrt(groups * area / max_cells)))


@njit(**KERNEL)
def group_cells(xy: np.ndarray, group: np.ndarray, groups: int, cell: float) -> Cells:
    """sample_cells of each of `groups` groups of the samples apart (`group`: each one's, such as
    its ring), on one grid: group g's cells are g x (the grid's cells) on (starts: groups x cells + 1)."""
    x0, y0 = xy[:, 0].min(), xy[:, 1].min()
    nx, ny = int((xy[:, 0].max() - x0) / cell) + 1, int((xy[:, 1].max() - y0) / cell) + 1
    home = np.empty(len(xy), np.int64)
    for i in range(len(xy)):
        home[i] = group[i] * nx * ny + int((xy[i, 1] - y0) / cell) * nx + int((xy[i, 0] - x0) / cell)
    order, starts = group_order(home, groups * nx * ny)
    ordered = np.empty((len(xy), 2))
    for j in range(len(xy)):
        ordered[j, 0], ordered[j, 1] = xy[order[j], 0], xy[order[j], 1]
    return order, starts, x0, y0, nx, ny, ordered


@njit(nogil=True, cache=True)
def nearest_within(
    cells: Cells,
    where: tuple[float, int, float],
    at: tuple[float, float],
    row_d: np.ndarray,
    row_i: np.ndarray,
) -> int:
    """The len(row_d) points of one group nearest the point `at` and nearer than a reach, nearest
    first, into (row_d distances, row_i indices); how many there are. where: (cell side, group (0
    for sample_cells), reach, inf for none). Searched ring of cells by ring of cells about the point
    until no cell left can hold a nearer one; squared distances, each cell's points read side by
    side (a quarter less time than reading them through the order)."""
    order, starts, x0, y0, nx, ny, ordered = cells
    cell, group, reach = where
    base, size, found = group * nx * ny, len(row_d), 0
    px, py = at
    cx = min(max(int((px - x0) // cell), 0), nx - 1)
    cy = min(max(int((py - y0) // cell), 0), ny - 1)
    steps = max(nx, ny) + 1
    if np.isfinite(reach):
        steps = min(steps, int(reach // cell) + 2)
    reach_2 = reach * reach
    for step in range(steps if size > 0 else 0):
        for gy in range(max(cy - step, 0), min(cy + step, ny - 1) + 1):
            edge = gy == cy - step or gy == cy + step
            for gx in range(max(cx - step, 0), min(cx + step, nx - 1) + 1):
                if not edge and cx - step < gx < cx + step:
                    continue
                c = base + gy * nx + gx
                for j in range(starts[c], starts[c + 1]):
                    d = (ordered[j, 0] - px) ** 2 + (ordered[j, 1] - py) ** 2
                    if d < reach_2 and (found < size or d < row_d[size - 1]):
                        found = _insert(row_d, row_i, found, d, j)
        # every point nearer than the searched block's nearest outside edge has been seen
        inner = min(
            px - (x0 + (cx - step) * cell), x0 + (cx + step + 1) * cell - px,
            py - (y0 + (cy - step) * cell), y0 + (cy + step + 1) * cell - py,
        )  # fmt: skip
        if inner >= reach or (found == size and inner >= 0 and row_d[size - 1] <= inner * inner):
            break
    for m in range(found):
        row_d[m], row_i[m] = np.sqrt(row_d[m]), order[row_i[m]]
    return found


@njit(nogil=True, cache=True, inline="always")
def _insert(row_d: np.ndarray, row_i: np.ndarray, found: int, d: float, sample: int) -> int:
    """Put (d, sample) into the sorted (row_d, row_i) holding `found`, dropping the last if full."""
    slot = min(found, len(row_d) - 1)
    while slot > 0 and row_d[slot - 1] > d:
        row_d[slot], row_i[slot] = row_d[slot - 1], row_i[slot - 1]
        slot -= 1
    row_d[slot], row_i[slot] = d, sample
    return min(found + 1, len(row_d))


@njit(**KERNEL)
def pairs_within(xy: np.ndarray, cells: Cells, cell: float, radius: float) -> np.ndarray:
    """(P, 2) every pair i < j of points `xy` at most `radius` apart, grouped by i; `cells`: sample_cells
    of `xy` with side `cell` >= radius (a pair lies in neighbouring cells)."""
    order, starts, x0, y0, nx, ny, _ = cells
    count = np.zeros(len(xy) + 1, np.int64)
    for sweep in range(2):  # count each point's partners, then write them where the counts say
        pairs = np.empty((count[-1] if sweep else 0, 2), np.int64)
        filled = count[:-1].copy()
        for i in range(len(xy)):
            cx, cy = int((xy[i, 0] - x0) / cell), int((xy[i, 1] - y0) / cell)
            for gy in range(max(cy - 1, 0), min(cy + 1, ny - 1) + 1):
                for gx in range(max(cx - 1, 0), min(cx + 1, nx - 1) + 1):
                    c = gy * nx + gx
                    for m in range(starts[c], starts[c + 1]):
                        j = order[m]
                        if j > i and (xy[i, 0] - xy[j, 0]) ** 2 + (xy[i, 1] - xy[j, 1]) ** 2 <= radius * radius:
                            if sweep:
                                pairs[filled[i], 0], pairs[filled[i], 1] = i, j
                                filled[i] += 1
                            else:
                                count[i + 1] += 1
        if not sweep:
            count = np.cumsum(count)
    return pairs


@njit(**KERNEL)
def k_nearest(cells: Cells, cell: float, at: np.ndarray, index: np.ndarray, start: int, stop: int) -> None:
    """For query points at[start:stop]: the indices of the k nearest points (index's width; at most
    their number), nearest first, into `index`; `cells`: sample_cells of the points with side
    `cell`."""
    k = min(index.shape[1], len(cells[0]))
    dist = np.empty(k)
    for q in range(start, stop):
        nearest_within(cells, (cell, 0, np.inf), (at[q, 0], at[q, 1]), dist, index[q, :k])


@njit(**KERNEL)
def k_nearest_in_group(
    cells: Cells,
    where: tuple[float, float],
    at: np.ndarray,
    at_group: np.ndarray,
    dist: np.ndarray,
    index: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """For query points at[start:stop] of groups at_group: the nearest points of the same group
    nearer than a reach, nearest first, into (dist, index) rows (the rest inf and -1); `cells`:
    group_cells of the points, where: (its cell side, the reach)."""
    cell, reach = where
    for q in range(start, stop):
        dist[q, :], index[q, :] = np.inf, -1
        nearest_within(cells, (cell, at_group[q], reach), (at[q, 0], at[q, 1]), dist[q], index[q])


@njit(**KERNEL)
def group_order(group: np.ndarray, groups: int) -> tuple[np.ndarray, np.ndarray]:
    """The indices of `group` (N,) (values in [0, groups)) by group, each group's in ascending order
    (np.argsort(group, kind="stable"), by counting), and where each group's run starts (groups + 1,)."""
    starts = np.zeros(groups + 1, np.int64)
    for i in range(len(group)):
        starts[group[i] + 1] += 1
    starts = np.cumsum(starts)
    filled = starts[:-1].copy()
    order = np.empty(len(group), np.int64)
    for i in range(len(group)):
        order[filled[group[i]]] = i
        filled[group[i]] += 1
    return order, starts


@njit(**KERNEL)
def every_nth_by_group(group: np.ndarray, key: np.ndarray, groups: int, step: int) -> np.ndarray:
    """The points at every `step`-th place (the first, the step + 1-th, ...) of their order by group
    and then by `key` within a group, ties by index (np.lexsort((key, group))), in ascending order."""
    order, starts = group_order(group, groups)
    chosen = np.zeros(len(group), np.bool_)
    for g in range(groups):
        members = order[starts[g] : starts[g + 1]]
        within = np.argsort(key[members], kind="mergesort")  # stable: ties keep the index order
        for m in range(len(members)):
            if (starts[g] + m) % step == 0:
                chosen[members[within[m]]] = True
    return np.flatnonzero(chosen)


@njit(**KERNEL)
def radix_order(keys: np.ndarray, key_bits: int) -> np.ndarray:
    """The stable ascending order of non-negative integer `keys` below 2^key_bits
    (np.argsort(keys, kind="stable")): group_order by 12 bits at a time, the lowest first."""
    order = np.arange(len(keys))
    for shift in range(0, max(key_bits, 1), 12):
        digits = (keys[order] >> shift) & 4095
        order = order[group_order(digits, 4096)[0]]
    return order
