"""Live mode's depth image (rig.pipeline.organised.organised_depth) of a pair whose camera rays meet
the planes of coded projector columns or rows, in one pass per band of rows: each row triangulated,
its isolated points dropped and its depth written, three rows held at a time. The three passes it
replaces (rig.kernels.dense.plane_triangulate, reject_isolated, blank_unkept) wrote and read back a
ray image, a depth image and two masks: some 300 MB of memory traffic for a 12 MP frame. The same
float32 operations as theirs, so the same depths to the bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL, Image


@njit(**KERNEL, error_model="numpy")  # a float division by zero is inf, as numpy's: no branch per pixel
def plane_depth(
    coded: Image,
    valid: Image,
    terms: tuple[np.float32, np.float32, np.float32, np.float32],
    c: Image,
    d: Image,
    along_axis: Image,
    jump: tuple[bool, np.float32, int],
    out: Image,
    top: int,
    bottom: int,
) -> int:
    """Rows [top, bottom) of the depth image: each pixel's depth along the camera axis where its
    ray meets its coded plane (rig.kernels.dense.plane_triangulate, `terms` its a, b, scale and
    shift) and, with `jump` (whether to test, the largest jump, the least support), it has at least
    that many of its 8 neighbours on the image within the jump (reject_isolated); NaN elsewhere.
    Returns the pixels with a depth."""
    height, width = coded.shape
    depths, decoded = np.empty((3, width), np.float32), np.empty((3, width), np.bool_)
    support = np.empty(width, np.int32)
    testing, max_jump, min_support = jump
    nan, kept = np.float32(np.nan), 0
    support[:] = min_support  # untested: every decoded point is kept
    for y in range(max(top - 1, 0), min(top + 1, bottom)):  # the row above the band, and its first
        _plane_row(coded, valid, terms, c, d, along_axis, y, depths, decoded)
    for y in range(top, bottom):
        if y + 1 < height:
            _plane_row(coded, valid, terms, c, d, along_axis, y + 1, depths, decoded)
        if testing:
            _support(depths, y, height, max_jump, support)
        here = y % 3
        for x in range(width):  # no branch per pixel: the loop runs in vector lanes
            keep = decoded[here, x] & (support[x] >= min_support)
            kept += keep
            out[y, x] = depths[here, x] if keep else nan
    return kept


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _plane_row(
    coded: Image,
    valid: Image,
    terms: tuple[np.float32, np.float32, np.float32, np.float32],
    c: Image,
    d: Image,
    along_axis: Image,
    y: int,
    depths: np.ndarray,
    decoded: np.ndarray,
) -> None:
    """Row y's depths and whether each pixel decoded, into row y % 3 of `depths` and `decoded`:
    rig.kernels.dense.plane_triangulate's steps."""
    nan, tiny, one, zero = np.float32(np.nan), np.float32(1e-3), np.float32(1), np.float32(0)
    a, b, scale, shift = terms
    at = y % 3
    for x in range(coded.shape[1]):
        u = coded[y, x]
        denominator = c[y, x] + d[y, x] * u
        normalised = u * scale + shift
        s = (a + b * u) / denominator
        ok = valid[y, x] and abs(denominator) >= tiny * np.sqrt(one + normalised * normalised) and s > zero
        s = s if ok else nan
        decoded[at, x] = ok
        depths[at, x] = s * along_axis[y, x]


@njit(nogil=True, cache=True)
def _support(depths: np.ndarray, y: int, height: int, max_jump: np.float32, support: np.ndarray) -> None:
    """rig.kernels.dense._support_row from the three rows held (row k in depths[k % 3])."""
    width = depths.shape[1]
    if y == 0 or y == height - 1 or width < 2:
        for x in range(width):
            support[x] = _support_at(depths, y, x, height, max_jump)
        return
    above, here, below = depths[(y - 1) % 3], depths[y % 3], depths[(y + 1) % 3]
    support[0] = _support_at(depths, y, 0, height, max_jump)
    support[width - 1] = _support_at(depths, y, width - 1, height, max_jump)
    for x in range(1, width - 1):  # no bounds to check: a loop the compiler vectorises
        z = here[x]
        count = np.int32(abs(z - above[x - 1]) <= max_jump) + np.int32(abs(z - above[x]) <= max_jump)
        count += np.int32(abs(z - above[x + 1]) <= max_jump) + np.int32(abs(z - here[x - 1]) <= max_jump)
        count += np.int32(abs(z - here[x + 1]) <= max_jump) + np.int32(abs(z - below[x - 1]) <= max_jump)
        count += np.int32(abs(z - below[x]) <= max_jump) + np.int32(abs(z - below[x + 1]) <= max_jump)
        support[x] = count


@njit(nogil=True, cache=True)
def _support_at(depths: np.ndarray, y: int, x: int, height: int, max_jump: np.float32) -> int:
    """rig.kernels.dense._support_at_border from the three rows held."""
    width, support, z = depths.shape[1], 0, depths[y % 3, x]
    for yy in range(max(y - 1, 0), min(y + 2, height)):
        for xx in range(max(x - 1, 0), min(x + 2, width)):
            if (yy != y or xx != x) and abs(z - depths[yy % 3, xx]) <= max_jump:
                support += 1
    return support
