"""The inner disc inside the innermost ring, filled from the surface all around it.

No ring crosses the disc, so no triangle covers it; but where the innermost ring closes around it,
the triangles between rings 0 and 1 give every pixel on its border a point, two pixels deep. Their
distances along the camera rays set the values and the slopes at the disc's edge, and the disc takes
the smoothest surface that meets both: the distance whose summed squared Laplacian over the image is
least (a thin plate, biharmonic inside the disc). Unlike a fit to the nearest samples, which reach
the pixel from one side of the ring only and extrapolate, every point of the disc hears the whole
ring. A disc the ring does not close around (a shadow, a depth step, the image's edge crossing it) is
left to the neighbourhood fit (rig.pipeline.fill); either way the projector's check that a point lies
in the band its pixel read still applies.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve

from rig.geometry import CameraModel

_MIN_DISC_SHARE = 0.5  # a hole is the inner disc when at least this share of it read annulus 0 ...
_MIN_CANDIDATE_SHARE = 0.95  # ... and nearly all of it is lit, read, and uncovered surface
# The sparse solve grows faster than the disc (idle: 11,684 px 0.2-0.3 s, 31,428 px 0.8 s, 101,780 px
# 5 s): a larger disc (rings far from the surface's centre) is left to the neighbourhood fit.
_MAX_DISC_PX = 12_000
_NEIGHBOURS = ((0, 1), (0, -1), (1, 0), (-1, 0))
_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))


def disc_points(
    grid: np.ndarray, covered: np.ndarray, candidate: np.ndarray, annulus: np.ndarray, camera: CameraModel
) -> np.ndarray:
    """A point (N, 3) for each flat candidate pixel `candidate` (sorted; reading `annulus`, (N,))
    inside an inner disc the covered pixels (`covered`, flat bool; their points in `grid`, flat
    (H*W, 3)) close around; NaN for the others."""
    found = np.full((len(candidate), 3), np.nan)
    if not (annulus == 0).any():  # no pixel read the disc: nothing to label
        return found
    shape = (camera.height, camera.width)
    uncovered = (~covered).reshape(shape).astype(np.uint8)
    _, label, stats, _ = cv2.connectedComponentsWithStats(uncovered, connectivity=4)
    candidate_label = label.ravel()[candidate]
    for k in _disc_holes(candidate_label, annulus == 0, stats, shape):
        x, y, w, h = (int(v) for v in stats[k, :4])
        box = (slice(y - 2, y + h + 2), slice(x - 2, x + w + 2))
        hole, in_box = label[box] == k, _flat_of(box, shape)
        distance = _thin_plate(hole, np.where(covered[in_box], _ray_distances(grid, camera, in_box), np.nan))
        if distance is None:
            continue
        flat = in_box[hole]
        position = np.minimum(np.searchsorted(candidate, flat), len(candidate) - 1)  # candidate is sorted
        wanted = candidate[position] == flat
        flat, t, position = flat[wanted], distance[hole][wanted], position[wanted]
        origins, directions = camera.pixel_rays
        found[position] = np.asarray(origins[flat]) + t[:, None] * np.asarray(directions[flat])
    return found


def _flat_of(box: tuple[slice, slice], shape: tuple[int, int]) -> np.ndarray:
    """(h, w) the flat image index of every pixel of `box`."""
    rows, cols = np.mgrid[box[0], box[1]]
    return rows * shape[1] + cols


def _disc_holes(
    candidate_label: np.ndarray, reads_disc: np.ndarray, stats: np.ndarray, shape: tuple[int, int]
) -> list[int]:
    """The uncovered components that are an inner disc closed in by covered pixels: off the image's
    border (two pixels, for the slopes), no larger than _MAX_DISC_PX, mostly annulus 0, and nearly
    all candidates (`candidate_label`: each candidate pixel's component; `reads_disc`: which of them
    read annulus 0)."""
    size = stats[:, cv2.CC_STAT_AREA]
    disc = np.bincount(candidate_label[reads_disc], minlength=len(stats))
    candidates = np.bincount(candidate_label, minlength=len(stats))
    x, y, w, h = (stats[:, i] for i in range(4))
    inside = (x >= 2) & (y >= 2) & (x + w <= shape[1] - 2) & (y + h <= shape[0] - 2)
    keep = inside & (size <= _MAX_DISC_PX) & (disc >= _MIN_DISC_SHARE * size)
    keep &= candidates >= _MIN_CANDIDATE_SHARE * size
    return [int(k) for k in np.flatnonzero(keep)]


def _ray_distances(grid: np.ndarray, camera: CameraModel, flat: np.ndarray) -> np.ndarray:
    """The points of `grid` (flat, (H*W, 3)) at pixels `flat` (any shape) as distances along their own
    rays, shaped like `flat`; NaN where there is none."""
    origins, directions = camera.pixel_rays
    offset = grid[flat] - np.asarray(origins[flat])
    return np.einsum("...j,...j->...", offset, np.asarray(directions[flat]))


def _thin_plate(hole: np.ndarray, known: np.ndarray) -> np.ndarray | None:
    """(h, w) `known` with the pixels of `hole` filled so that the sum of squared 5-point Laplacians
    over the hole and its first ring of neighbours is least; None where the hole is not closed in
    (a neighbour of it with no known value)."""
    ring = cv2.dilate(hole.astype(np.uint8), _CROSS).astype(bool) & ~hole
    if not np.isfinite(known[ring]).all():
        return None
    unknown = np.full(hole.shape, -1, dtype=np.int64)
    unknown[hole] = np.arange(int(hole.sum()))
    centre_r, centre_c = np.nonzero(hole | ring)
    stencil = [(0, 0, -4.0)] + [(dr, dc, 1.0) for dr, dc in _NEIGHBOURS]
    usable = np.ones(len(centre_r), dtype=bool)
    for dr, dc, _ in stencil:  # a Laplacian reaching a pixel neither filled nor known is left out
        r, c = centre_r + dr, centre_c + dc
        usable &= hole[r, c] | np.isfinite(known[r, c])
    centre_r, centre_c = centre_r[usable], centre_c[usable]
    rows, cols, values = [], [], []
    rhs = np.zeros(len(centre_r))
    for dr, dc, weight in stencil:
        r, c = centre_r + dr, centre_c + dc
        free = hole[r, c]
        rows.append(np.flatnonzero(free))
        cols.append(unknown[r[free], c[free]])
        values.append(np.full(int(free.sum()), weight))
        rhs[~free] -= weight * known[r[~free], c[~free]]
    laplacian = sparse.csr_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=(len(centre_r), int(hole.sum()))
    )
    normal = (laplacian.T @ laplacian).tocsc()
    filled = known.copy()
    filled[hole] = spsolve(normal, laplacian.T @ rhs)
    return filled
