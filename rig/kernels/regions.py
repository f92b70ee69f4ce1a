"""A surface's pixel footprints and connected regions (rig.evaluate.regions), compiled by numba.

Every simulated scan is judged by area against the truth, 1.3 million pixels on the default bench:
as numpy passes and SciPy's connected components over a sparse graph this took 0.7 s per view
(line profile, scratch). Two loops over the rows do it here. A region's errors are summed, and
the areas of labels totalled, in one pass over the points each, with no copies of them. Compiled on
first use and cached beside this file.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(**KERNEL)
def joins_and_areas(grid: np.ndarray, valid: np.ndarray, limit: np.ndarray) -> tuple[np.ndarray, ...]:
    """Which pixels join their right neighbour (H, W-1) and the one below (H-1, W): both valid and
    their points within `limit` (H, W, the pixel's own) of each other; and each pixel's area (H, W):
    the cross product of its steps along the rows and the columns (the mean of its two joined
    differences, or the one it has), or the square of the one step it has, 0 with none."""
    height, width = valid.shape
    right = np.zeros((height, max(width - 1, 0)), np.bool_)
    down = np.zeros((max(height - 1, 0), width), np.bool_)
    for y in range(height):
        for x in range(width):
            if not valid[y, x]:
                continue
            if x + 1 < width and valid[y, x + 1]:
                right[y, x] = _apart(grid, y, x, y, x + 1) <= limit[y, x]
            if y + 1 < height and valid[y + 1, x]:
                down[y, x] = _apart(grid, y, x, y + 1, x) <= limit[y, x]
    area = np.zeros((height, width))
    su = np.zeros(3)
    sv = np.zeros(3)
    for y in range(height):
        for x in range(width):
            if not valid[y, x]:
                continue
            has_u = _step(grid, y, x, 0, 1, x > 0 and right[y, x - 1], x + 1 < width and right[y, x], su)
            has_v = _step(grid, y, x, 1, 0, y > 0 and down[y - 1, x], y + 1 < height and down[y, x], sv)
            if has_u and has_v:
                cx = su[1] * sv[2] - su[2] * sv[1]
                cy = su[2] * sv[0] - su[0] * sv[2]
                cz = su[0] * sv[1] - su[1] * sv[0]
                area[y, x] = np.sqrt(cx * cx + cy * cy + cz * cz)
            elif has_u:
                area[y, x] = su[0] ** 2 + su[1] ** 2 + su[2] ** 2
            elif has_v:
                area[y, x] = sv[0] ** 2 + sv[1] ** 2 + sv[2] ** 2
    return right, down, area


@njit(**KERNEL)
def _apart(grid: np.ndarray, y0: int, x0: int, y1: int, x1: int) -> float:
    total = 0.0
    for c in range(3):
        total += (float(grid[y1, x1, c]) - float(grid[y0, x0, c])) ** 2
    return np.sqrt(total)


@njit(**KERNEL)
def _step(grid: np.ndarray, y: int, x: int, dy: int, dx: int, back: bool, ahead: bool, out: np.ndarray) -> bool:
    """The step to the next pixel along (dy, dx) into `out`: the mean of the joined differences
    behind and ahead, or the one there is; False with neither."""
    if not (back or ahead):
        return False
    count = 0
    for c in range(3):
        out[c] = 0.0
    if back:
        for c in range(3):
            out[c] += float(grid[y, x, c]) - float(grid[y - dy, x - dx, c])
        count += 1
    if ahead:
        for c in range(3):
            out[c] += float(grid[y + dy, x + dx, c]) - float(grid[y, x, c])
        count += 1
    for c in range(3):
        out[c] /= count
    return True


@njit(**KERNEL)
def joined_labels(right: np.ndarray, down: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """A label per valid pixel (row-major) of the graph joining pixels through `right` and `down`,
    numbered in the order of each region's first pixel (as SciPy's connected components number
    them). Node numbers are held for two rows at a time (the row being joined and the one below),
    not for the whole image."""
    height, width = valid.shape
    count = 0
    for y in range(height):
        for x in range(width):
            count += valid[y, x]
    parent = np.empty(count, np.int32)  # int32: half the memory of int64
    for n in range(count):
        parent[n] = n
    node, below = np.empty(width, np.int32), np.empty(width, np.int32)
    numbered = _number_row(valid, 0, 0, node) if height else 0
    for y in range(height):
        if y + 1 < height:
            numbered = _number_row(valid, y + 1, numbered, below)
        for x in range(width):
            if not valid[y, x]:
                continue
            if x + 1 < width and right[y, x] and valid[y, x + 1]:  # a join to a pixel not valid is none
                _union(parent, node[x], node[x + 1])
            if y + 1 < height and down[y, x] and valid[y + 1, x]:
                _union(parent, node[x], below[x])
        node, below = below, node
    # Each root is its region's first node (_union) and every parent comes before its child, so the
    # parents turn into labels in place, in one pass: a child takes its parent's, labelled already.
    regions = 0
    for n in range(count):
        if parent[n] == n:
            parent[n] = regions
            regions += 1
        else:
            parent[n] = parent[parent[n]]
    return parent


@njit(**KERNEL)
def _number_row(valid: np.ndarray, y: int, first: int, node: np.ndarray) -> int:
    """Row y's valid pixels' nodes, numbered on from `first`, into `node`; the next free number."""
    for x in range(valid.shape[1]):
        if valid[y, x]:
            node[x] = first
            first += 1
    return first


@njit(**KERNEL)
def _find(parent: np.ndarray, n: int) -> int:
    root = n
    while parent[root] != root:
        root = parent[root]
    while parent[n] != root:  # path compression
        parent[n], n = root, parent[n]
    return root


@njit(**KERNEL)
def _union(parent: np.ndarray, a: int, b: int) -> None:
    ra, rb = _find(parent, a), _find(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)


@njit(**KERNEL)
def ordered_quantile(
    values: np.ndarray, weights: np.ndarray, order: np.ndarray, labels: np.ndarray, label: int, q: float
) -> float:
    """rig.evaluate.regions.weighted_quantile of the points whose `labels` are `label` (every point
    for an empty `labels`), taken in `order` (the values' stable ascending order): their float64
    weights summed in that order (as np.cumsum sums them), the first value at which the sum reaches
    `q` of their total. Two passes over `order`, no arrays of the region's own. ValueError for no
    points."""
    every = len(labels) == 0
    total, last = 0.0, -1
    for i in order:
        if every or labels[i] == label:
            total += weights[i]
            last = i
    if last < 0:
        raise ValueError("a quantile of no points")
    threshold = q * total
    running = 0.0
    for i in order:
        if every or labels[i] == label:
            running += weights[i]
            if running >= threshold:
                return float(values[i])
    return float(values[last])


@njit(**KERNEL)
def region_sums(
    values: np.ndarray, weights: np.ndarray, labels: np.ndarray, slot: np.ndarray, slots: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per slot, the float64 sum of the weights, of value^2 x weight, and the largest value: slot 0
    every point, slot slot[labels[i]] (1 or more) those of a judged label (-1: a label not judged).
    One pass, no copies of a region's points (rig.evaluate.regions.region_errors); summed one point
    at a time, where numpy sums pairwise: the same to the last few bits."""
    area, square, largest = np.zeros(slots), np.zeros(slots), np.full(slots, -np.inf)
    for i in range(len(values)):
        value, weight = float(values[i]), float(weights[i])
        judged = slot[labels[i]] if labels[i] >= 0 else -1  # a label < 0 (no region) in none
        for k in (0, judged):
            if k >= 0:
                area[k] += weight
                square[k] += value * value * weight  # each term as numpy's (d^2) w; summed in order
                largest[k] = max(largest[k], value)
    return area, square, largest


@njit(**KERNEL)
def label_totals(labels: np.ndarray, weights: np.ndarray, count: int) -> np.ndarray:
    """np.bincount(labels, weights) over the labels >= 0 (a label < 0: no region; both flat),
    `count` long, summed in the same order: with no copies of the labels (bincount takes them as
    int64) or of the counted points' own."""
    total = np.zeros(count)
    for i in range(len(labels)):
        if labels[i] >= 0:
            total[labels[i]] += weights[i]
    return total
