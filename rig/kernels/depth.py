"""Live mode's depth image (rig.pipeline.organised.organised_depth) of a pair whose camera rays meet
the planes of coded projector columns or rows, in one pass per band of rows: each row triangulated,
its isolated points dropped and its depth written, three rows held at a time. The three passes it
replaces (rig.kernels.dense.plane_triangulate, reject_isolated, blank_unkept) wrote and read back a
ray image, a depth image and two masks: some 300 MB of memory traffic for a 12 MP frame. Its pixel's
point and neighbours' count are theirs (plane_point, support_of_rows), so the same depths to the bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL, Image
from rig.kernels.dense import plane_point, support_of_rows

# a pair's coded planes at each pixel: coded coordinate, valid, (a, b, scale, shift), c, d, ray along the axis
Plane = tuple[Image, Image, tuple[np.float32, np.float32, np.float32, np.float32], Image, Image, Image]


@njit(**KERNEL, error_model="numpy")  # a float division by zero is inf, as numpy's: no branch per pixel
def plane_depth(plane: Plane, isolation: tuple[bool, np.float32, int], out: Image, top: int, bottom: int) -> int:
    """Rows [top, bottom) of the depth image: each pixel's depth along the camera axis where its
    ray meets its coded plane (`plane`: the coded coordinates, where valid, a, b, scale and shift,
    c, d and the rays' components along the axis, as rig.kernels.dense.plane_triangulate reads
    them) and, with `isolation` (whether to test, the largest jump, the least support), it has at
    least that many of its 8 neighbours on the image within the jump (reject_isolated); NaN
    elsewhere. Returns the pixels with a depth."""
    height, width = plane[0].shape
    depths, decoded = np.empty((3, width), np.float32), np.empty((3, width), np.bool_)
    support = np.empty(width, np.int32)
    testing, max_jump, min_support = isolation
    nan, kept = np.float32(np.nan), 0
    support[:] = min_support  # untested: every decoded point is kept
    for y in range(max(top - 1, 0), min(top + 1, bottom)):  # the row above the band, and its first
        _plane_row(plane, y, depths, decoded)
    for y in range(top, bottom):
        if y + 1 < height:
            _plane_row(plane, y + 1, depths, decoded)
        if testing:  # the rows beside y as reject_isolated reads them: y's own where y has none
            beside = (depths[max(y - 1, 0) % 3], depths[y % 3], depths[min(y + 1, height - 1) % 3])
            support_of_rows(beside, y, height, max_jump, support)
        here = y % 3
        for x in range(width):  # no branch per pixel: the loop runs in vector lanes
            keep = decoded[here, x] & (support[x] >= min_support)
            kept += keep
            out[y, x] = depths[here, x] if keep else nan
    return kept


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _plane_row(plane: Plane, y: int, depths: np.ndarray, decoded: np.ndarray) -> None:
    """Row y's depths and whether each pixel decoded, into row y % 3 of `depths` and `decoded`, as
    rig.kernels.dense.plane_triangulate makes them."""
    coded, valid, terms, c, d, along_axis = plane
    at = y % 3
    for x in range(coded.shape[1]):
        s, ok = plane_point(coded[y, x], valid[y, x], c[y, x], d[y, x], terms)
        decoded[at, x] = ok
        depths[at, x] = s * along_axis[y, x]
