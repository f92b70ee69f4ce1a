"""The colour between the rings (rig.pipeline.colour), compiled by numba: each face's reach, corners
and share of area in one loop, and each pixel's weighted mean of its face's candidate samples in
another, instead of (pixels x candidates) numpy temporaries and a sparse product (130 ms for the
default bench's ring scan, against about 20 here); and each sample's nearest on its own ring, the
pixels' candidates, by a sweep along one of the ring's two widest axes, whichever each sample's
neighbours spread furthest along (a 4-D k-d tree took twice as long).
The pixels' distances are float32 about the samples' centre, as rig.pipeline.colour prepares them,
and their sums float64; the samples' distances to each other are float64."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL
from rig.kernels.cells import group_order
from rig.kernels.vectors import corner_cross, row_distance

_NO_WEIGHT = 1e-30  # a pixel no candidate reaches divides by this: its colour is 0


@njit(**KERNEL)
def face_terms(
    vertices: np.ndarray, faces: np.ndarray, ring: np.ndarray, reach2: np.ndarray, corners: np.ndarray, area: np.ndarray
) -> None:
    """Per face (F, 3) of samples `vertices` on rings `ring`: its squared reach `reach2` (twice its
    longest edge, squared, float32), a corner on its lower and on its upper ring `corners` (F, 2:
    the first of each), and a third of its area added to each corner's `area` (M,)."""
    for f in range(len(faces)):
        longest = 0.0
        for k in range(3):
            longest = max(longest, row_distance(vertices, faces[f, (k + 1) % 3], faces[f, k]))
        reach2[f] = np.float32((2.0 * longest) ** 2)
        low = high = 0
        for k in range(1, 3):
            low = k if ring[faces[f, k]] < ring[faces[f, low]] else low
            high = k if ring[faces[f, k]] > ring[faces[f, high]] else high
        corners[f, 0], corners[f, 1] = faces[f, low], faces[f, high]
        cx, cy, cz = corner_cross(vertices, faces[f, 0], faces[f, 1], faces[f, 2])
        third = 0.5 * np.sqrt(cx**2 + cy**2 + cz**2) / 3.0
        for k in range(3):
            area[faces[f, k]] += third


@njit(**KERNEL)
def mix_colours(
    samples: np.ndarray,
    area: np.ndarray,
    colours: np.ndarray,
    candidates: tuple[np.ndarray, np.ndarray],
    reach2: np.ndarray,
    pixels: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    settings: tuple[bool, int, float],
    out: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """Colours out[pixel[p]] (out: flat H*W x 3) of pixels p in [start, stop) of pixels = (grid,
    pixel, owner, centre): each at grid[pixel[p]] (flat H*W x 3, taken about the samples' `centre`
    in float32), in face owner[p] (-1: none, left as it is), from each face's candidates within its
    squared reach `reach2` (F,): settings (nearest, L, softening squared): the mean of the L nearest
    within reach, or the mean weighted by `area` / (d^2 + softening). candidates: (along (M, k),
    each sample's nearest on its ring, index M for none, far beyond any reach; corners (F, 2),
    face_terms'): a face's are its lower corner's along, then its upper's. samples: (3, M + 1)
    float32 positions as rows; area (M + 1,); colours (M + 1, 3)."""
    nearest, count, softening = settings
    along, corners = candidates
    grid, pixel, owner, centre = pixels
    k = along.shape[1]
    width = 2 * k
    d2 = np.empty(width, np.float32)
    order, which = np.empty(width, np.int64), np.empty(width, np.int64)
    for p in range(start, stop):
        face = owner[p]
        if face < 0:  # not in a face: rig.pipeline.colour gives it its nearest sample's
            continue
        reach = reach2[face]
        for j in range(width):  # the lower corner's along-ring neighbours, then the upper's
            which[j] = along[corners[face, 0], j] if j < k else along[corners[face, 1], j - k]
        at = pixel[p]
        x, y = np.float32(grid[at, 0] - centre[0]), np.float32(grid[at, 1] - centre[1])
        z = np.float32(grid[at, 2] - centre[2])
        for j in range(width):
            s = which[j]
            dx = samples[0, s] - x
            dy = samples[1, s] - y
            dz = samples[2, s] - z
            d2[j] = dx * dx + dy * dy + dz * dz
        total, r, g, b = 0.0, 0.0, 0.0, 0.0
        if nearest:
            taken = _nearest_within(d2, reach, count, order)
            for m in range(taken):
                s = which[order[m]]
                total += 1.0
                r, g, b = r + colours[s, 0], g + colours[s, 1], b + colours[s, 2]
        else:
            for j in range(width):
                if d2[j] > reach:
                    continue
                s = which[j]
                w = area[s] / (d2[j] + np.float32(softening))
                total += w
                r, g, b = r + w * colours[s, 0], g + w * colours[s, 1], b + w * colours[s, 2]
        total = max(total, _NO_WEIGHT)
        out[at, 0], out[at, 1], out[at, 2] = r / total, g / total, b / total


@njit(nogil=True, cache=True)
def _nearest_within(d2: np.ndarray, reach: float, count: int, order: np.ndarray) -> int:
    """The positions of the up to `count` smallest of `d2` within `reach`, nearest first, in
    `order`; how many (an insertion sort: a face has a few dozen candidates)."""
    taken = 0
    for j in range(len(d2)):
        if d2[j] > reach:
            continue
        slot = min(taken, count - 1)
        if taken == count and d2[j] >= d2[order[slot]]:
            continue
        while slot > 0 and d2[order[slot - 1]] > d2[j]:
            order[slot] = order[slot - 1]
            slot -= 1
        order[slot] = j
        taken = min(taken + 1, count)
    return taken


@njit(**KERNEL)
def ring_sweeps(
    points: np.ndarray, ring: np.ndarray, rings: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each ring's samples (points (N, 3), ring (N,) in [0, rings)) in the order of their
    coordinate along the ring's widest axis and along its second widest (sweep 0 and 1), for
    nearest_on_ring: order (2, N) sample indices grouped by ring and, within one, by that
    coordinate (ties by index), key (2, N) the coordinates in that order, place (2, N) each
    sample's position in order, and where each ring's run starts (rings + 1,)."""
    by_ring, starts = group_order(ring, rings)
    order, key, place = np.empty((2, len(ring)), np.int64), np.empty((2, len(ring))), np.empty((2, len(ring)), np.int64)
    extent = np.empty(3)
    for g in range(rings):
        members = by_ring[starts[g] : starts[g + 1]]
        if len(members) == 0:
            continue
        for c in range(3):
            low = high = points[members[0], c]
            for m in members:
                low, high = min(low, points[m, c]), max(high, points[m, c])
            extent[c] = high - low
        axes = np.argsort(-extent, kind="mergesort")  # widest first; of equals, the first axis
        for sweep in range(2):
            values = np.empty(len(members))
            for m in range(len(members)):
                values[m] = points[members[m], axes[sweep]]
            within = np.argsort(values, kind="mergesort")  # stable: ties keep the index order
            for m in range(len(members)):
                at = starts[g] + m
                order[sweep, at], key[sweep, at] = members[within[m]], values[within[m]]
                place[sweep, members[within[m]]] = at
    return order, key, place, starts


@njit(**KERNEL)
def nearest_on_ring(
    points: np.ndarray,
    ring: np.ndarray,
    sweeps: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    named: tuple[np.ndarray, int],
    out: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """Each sample's `k` nearest samples of its own ring, itself among them (k = out.shape[1]),
    nearest first (ties by index): exactly, by a sweep along one axis, for samples [start, stop) of
    `points` (N, 3) on rings `ring` (N,). sweeps: ring_sweeps' order, key, place and ring starts.
    named (names (N,), none): a sample n is written as names[n], and `none` past a ring's last;
    out[names[n]] is filled. A sample further along the axis than the k-th nearest found so far is
    further in space too, so the sweep stops there: a few dozen samples are looked at, not the
    ring's thousands. Of the ring's two widest axes, each sample sweeps the one its k neighbours
    either side spread furthest along (at a ring's extreme along one axis, the samples bunch there,
    and both sides of the ring meet)."""
    names, none = named
    orders, keys, places, starts = sweeps
    k = out.shape[1]
    best_d2, best = np.empty(k), np.empty(k, np.int64)
    for me in range(start, stop):
        first, last = starts[ring[me]], starts[ring[me] + 1]
        spread_0, spread_1 = (
            _spread(keys[0], places[0, me], k, first, last),
            _spread(keys[1], places[1, me], k, first, last),
        )
        sweep = 0 if spread_0 >= spread_1 else 1
        order, key, p = orders[sweep], keys[sweep], places[sweep, me]
        found = 0
        left, right = p, p + 1
        while left >= first or right < last:
            gap_left = key[p] - key[left] if left >= first else np.inf
            gap_right = key[right] - key[p] if right < last else np.inf
            take_left = gap_left <= gap_right
            gap = gap_left if take_left else gap_right
            if found == k and gap * gap > best_d2[k - 1]:
                break
            j = order[left] if take_left else order[right]
            if take_left:
                left -= 1
            else:
                right += 1
            d2 = 0.0
            for c in range(3):
                d2 += (points[j, c] - points[me, c]) ** 2
            if found == k and (d2 > best_d2[k - 1] or (d2 == best_d2[k - 1] and j > best[k - 1])):
                continue
            slot = min(found, k - 1)
            while slot > 0 and (best_d2[slot - 1] > d2 or (best_d2[slot - 1] == d2 and best[slot - 1] > j)):
                best_d2[slot], best[slot] = best_d2[slot - 1], best[slot - 1]
                slot -= 1
            best_d2[slot], best[slot] = d2, j
            found = min(found + 1, k)
        for m in range(k):
            out[names[me], m] = names[best[m]] if m < found else none


@njit(nogil=True, cache=True, inline="always")
def _spread(key: np.ndarray, at: int, k: int, first: int, last: int) -> float:
    """How far the k samples either side of position `at` (within [first, last)) spread along `key`."""
    return key[min(at + k, last - 1)] - key[max(at - k, first)]
