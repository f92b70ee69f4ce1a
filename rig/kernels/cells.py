"""Image points sorted into a grid of square cells (a counting sort), compiled by numba: the
neighbour searches of rig.kernels.fill and rig.kernels.rings scan a point's few cells instead of a
k-d tree."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL

# order (the points' indices cell by cell), starts (where each cell's run starts, cells + 1),
# the grid's corner x0, y0 and its size in cells nx, ny
Cells = tuple[np.ndarray, np.ndarray, float, float, int, int]


@njit(**KERNEL)
def sample_cells(xy: np.ndarray, cell: float) -> Cells:
    """The samples `xy` (M, 2) sorted into square cells of side `cell`: their indices cell by cell,
    where each cell's run starts ((cells + 1,)), the grid's corner and its size in cells."""
    x0, y0 = xy[:, 0].min(), xy[:, 1].min()
    nx, ny = int((xy[:, 0].max() - x0) / cell) + 1, int((xy[:, 1].max() - y0) / cell) + 1
    home = np.empty(len(xy), np.int64)
    starts = np.zeros(nx * ny + 1, np.int64)
    for i in range(len(xy)):
        home[i] = int((xy[i, 1] - y0) / cell) * nx + int((xy[i, 0] - x0) / cell)
        starts[home[i] + 1] += 1
    starts = np.cumsum(starts)
    filled = starts[:-1].copy()
    order = np.empty(len(xy), np.int64)
    for i in range(len(xy)):
        order[filled[home[i]]] = i
        filled[home[i]] += 1
    return order, starts, x0, y0, nx, ny


@njit(**KERNEL)
def pairs_within(xy: np.ndarray, cells: Cells, cell: float, radius: float) -> np.ndarray:
    """(P, 2) every pair i < j of points `xy` at most `radius` apart, grouped by i; `cells`: sample_cells
    of `xy` with side `cell` >= radius (a pair lies in neighbouring cells)."""
    order, starts, x0, y0, nx, ny = cells
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
def k_nearest(
    xy: np.ndarray, cells: Cells, cell: float, at: np.ndarray, index: np.ndarray, start: int, stop: int
) -> None:
    """For query points at[start:stop]: the indices of the k nearest points `xy` (index's width; at
    most len(xy)), nearest first, into `index`; `cells`: sample_cells of `xy` with side `cell`.
    Searched ring of cells by ring of cells about the query until no cell left can hold a nearer one."""
    order, starts, x0, y0, nx, ny = cells
    k = min(index.shape[1], len(xy))
    dist = np.empty(k)
    for q in range(start, stop):
        px, py = at[q, 0], at[q, 1]
        cx = min(max(int((px - x0) // cell), 0), nx - 1)
        cy = min(max(int((py - y0) // cell), 0), ny - 1)
        found = 0
        for step in range(max(nx, ny) + 1):
            for gy in range(max(cy - step, 0), min(cy + step, ny - 1) + 1):
                edge = gy == cy - step or gy == cy + step
                for gx in range(max(cx - step, 0), min(cx + step, nx - 1) + 1):
                    if not edge and cx - step < gx < cx + step:
                        continue
                    c = gy * nx + gx
                    for m in range(starts[c], starts[c + 1]):
                        s = order[m]
                        d = (xy[s, 0] - px) ** 2 + (xy[s, 1] - py) ** 2
                        if found == k and d >= dist[k - 1]:
                            continue
                        slot = min(found, k - 1)
                        while slot > 0 and dist[slot - 1] > d:
                            dist[slot], index[q, slot] = dist[slot - 1], index[q, slot - 1]
                            slot -= 1
                        dist[slot], index[q, slot] = d, s
                        found = min(found + 1, k)
            # every point nearer than the searched block's nearest outside edge has been seen
            inner = min(
                px - (x0 + (cx - step) * cell), x0 + (cx + step + 1) * cell - px,
                py - (y0 + (cy - step) * cell), y0 + (cy + step + 1) * cell - py,
            )  # fmt: skip
            if found == k and dist[k - 1] <= inner * inner:
                break
