"""The colour between the rings (rig.pipeline.colour), compiled by numba: each face's reach, corners
and share of area in one loop, and each pixel's weighted mean of its face's candidate samples in
another, instead of (pixels x candidates) numpy temporaries and a sparse product (130 ms for the
default bench's ring scan, against about 20 here). Distances are float32 about the samples'
centre, as rig.pipeline.colour prepares them; sums are float64."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL
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
    at: np.ndarray,
    owner: np.ndarray,
    settings: tuple[bool, int, float],
    out: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """Colours `out[start:stop]` (P, 3) of pixels at `at` (P, 3 float32, about the samples' centre)
    in faces `owner`, from each face's candidates within its squared reach `reach2` (F,): settings
    (nearest, L, softening squared): the mean of the L nearest within reach, or the mean weighted by
    `area` / (d^2 + softening). candidates: (along (M, k), each sample's nearest on its ring, index M
    for none, far beyond any reach; corners (F, 2), face_terms'): a face's are its lower corner's
    along, then its upper's. samples: (3, M + 1) float32 positions as rows; area (M + 1,); colours
    (M + 1, 3)."""
    nearest, count, softening = settings
    along, corners = candidates
    k = along.shape[1]
    width = 2 * k
    d2 = np.empty(width, np.float32)
    order, which = np.empty(width, np.int64), np.empty(width, np.int64)
    for p in range(start, stop):
        face = owner[p]
        reach = reach2[face]
        for j in range(width):  # the lower corner's along-ring neighbours, then the upper's
            which[j] = along[corners[face, 0], j] if j < k else along[corners[face, 1], j - k]
        for j in range(width):
            s = which[j]
            dx = samples[0, s] - at[p, 0]
            dy = samples[1, s] - at[p, 1]
            dz = samples[2, s] - at[p, 2]
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
        out[p, 0], out[p, 1], out[p, 2] = r / total, g / total, b / total


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
