"""The colour between the rings (rig.pipeline.colour), compiled by numba: each pixel's weighted mean
of its face's candidate samples in one loop, instead of (pixels x candidates) numpy temporaries
and a sparse product (130 ms for the default bench's ring scan, against a few here). Distances are
float32 about the samples' centre, as rig.pipeline.colour prepares them; sums are float64."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL

_NO_WEIGHT = 1e-30  # a pixel no candidate reaches divides by this: its colour is 0


@njit(**KERNEL)
def mix_colours(
    samples: np.ndarray,
    area: np.ndarray,
    colours: np.ndarray,
    candidates: np.ndarray,
    reach2: np.ndarray,
    at: np.ndarray,
    owner: np.ndarray,
    settings: tuple[bool, int, float],
    out: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """Colours `out[start:stop]` (P, 3) of pixels at `at` (P, 3 float32, about the samples' centre)
    in faces `owner`, from each face's `candidates` (F, C; index M is no sample, far beyond any
    reach) within its squared reach `reach2` (F,): settings (nearest, L, softening squared):
    the mean of the L nearest within reach, or the mean weighted by `area` / (d^2 + softening).
    samples: (3, M + 1) float32 positions as rows; area (M + 1,); colours (M + 1, 3)."""
    nearest, count, softening = settings
    width = candidates.shape[1]
    d2 = np.empty(width, np.float32)
    order = np.empty(width, np.int64)
    for p in range(start, stop):
        face = owner[p]
        reach = reach2[face]
        for j in range(width):
            s = candidates[face, j]
            dx = samples[0, s] - at[p, 0]
            dy = samples[1, s] - at[p, 1]
            dz = samples[2, s] - at[p, 2]
            d2[j] = dx * dx + dy * dy + dz * dz
        total, r, g, b = 0.0, 0.0, 0.0, 0.0
        if nearest:
            taken = _nearest_within(d2, reach, count, order)
            for m in range(taken):
                s = candidates[face, order[m]]
                total += 1.0
                r, g, b = r + colours[s, 0], g + colours[s, 1], b + colours[s, 2]
        else:
            for j in range(width):
                if d2[j] > reach:
                    continue
                s = candidates[face, j]
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
