"""Where a ring scan promises a surface: between two rings the camera sees on it.

A camera pixel at projector polar coordinates (rho, theta) about the rings' centre lies on the
projector's ray at angle theta, between the two rings around rho. The surface there is promised
when the camera sees both rings bound that stretch of surface: the piece of the annulus between the
two rings, within a narrow sector of angle about theta, that the pixel's surface region (rig.evaluate.
regions) holds lit and seen and connected to the pixel, touches both rings where they cross it clear
of its edge. Inside the innermost ring only that ring is needed. A strip with a ring on one side
alone, beyond the last ring a limb lets the camera see or up to a shadow's edge, is not promised:
nothing on its far side bounds it, and the surface there could only be extrapolated.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter

from rig.evaluate.regions import MIN_REGION_SHARE, joined_labels
from rig.workers import point_blocks

SECTOR_ARC_PX = 8.0  # projector pixels of arc, at its outer ring, of each sector of an annulus
CLEAR_PX = 2  # a ring is seen where it crosses surface this many camera pixels clear of its edge


def between_rings(
    rho: np.ndarray,
    theta: np.ndarray,
    region: np.ndarray,
    area: np.ndarray,
    seen: np.ndarray,
    radii: np.ndarray,
) -> np.ndarray:
    """(H, W) the pixels a ring set (`radii`, increasing) promises a surface at (see the module
    docstring), of the regions (`region` labels, -1 none) that hold at least MIN_REGION_SHARE of the
    `seen` area; `rho`, `theta` each pixel's projector polar coordinates about the rings' centre."""
    radii = np.asarray(radii, dtype=np.float64)
    labels = np.where(seen & np.isfinite(rho) & np.isfinite(theta), region, -1).astype(np.int32)
    counted = labels >= 0
    if not counted.any() or len(radii) == 0:
        return np.zeros(seen.shape, dtype=bool)
    per_label = np.bincount(labels[counted], weights=area[counted])
    judged = np.zeros(len(per_label), dtype=bool)
    judged[per_label >= MIN_REGION_SHARE * per_label.sum()] = True
    labels[counted & ~judged[np.maximum(labels, 0)]] = -1
    band, key = np.empty(seen.shape, np.int32), np.empty(seen.shape, np.int64)
    for rows in point_blocks(seen.shape[0], 64):  # a band of rows at a time: no image-sized temporaries
        # radii[band-1] <= rho < radii[band]
        band[rows] = np.searchsorted(radii, np.nan_to_num(rho[rows], nan=-1.0), side="right")
        key[rows] = np.where(labels[rows] >= 0, _cell(labels[rows], band[rows], theta[rows], radii), -1)
    pieces = _pieces(key)
    del key
    inner, outer = _bounded(band, labels, pieces, len(radii))
    piece = pieces[labels >= 0]
    ok = outer[piece] & (inner[piece] | (band[labels >= 0] == 0))  # the disc needs its ring only
    target = np.zeros(seen.shape, dtype=bool)
    target[labels >= 0] = ok
    return target


def _cell(labels: np.ndarray, band: np.ndarray, theta: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """A key per pixel for its (region, annulus, sector): each annulus is cut into sectors of
    SECTOR_ARC_PX of arc at its outer ring (the band beyond the last ring into one)."""
    outer = radii[np.minimum(band, len(radii) - 1)]
    sectors = np.maximum(8, np.ceil(2 * np.pi * outer / SECTOR_ARC_PX)).astype(np.int64)
    sector = np.floor((np.nan_to_num(theta) + np.pi) / (2 * np.pi) * sectors).astype(np.int64) % sectors
    sector[band >= len(radii)] = 0
    most = int(np.ceil(2 * np.pi * radii[-1] / SECTOR_ARC_PX)) + 8
    return (labels.astype(np.int64) * (len(radii) + 1) + band) * most + sector


def _pieces(key: np.ndarray) -> np.ndarray:
    """(H, W) a label per connected piece (4-neighbours) of pixels sharing one `key` (>= 0)."""
    right = (key[:, :-1] >= 0) & (key[:, :-1] == key[:, 1:])
    down = (key[:-1] >= 0) & (key[:-1] == key[1:])
    return joined_labels(right, down, np.ones(key.shape, bool)).reshape(key.shape)


def _bounded(band: np.ndarray, labels: np.ndarray, pieces: np.ndarray, rings: int) -> tuple[np.ndarray, np.ndarray]:
    """Per piece, whether its inner and its outer ring cross it: between two neighbouring pixels of
    one region, both CLEAR_PX clear of the region's edge (a ring edge the camera reads has surface
    around it, not a limb or a shadow's brink). Rings skipped between two pixels (a surface turned
    steeply away) bound no piece the camera sees."""
    window = 2 * CLEAR_PX + 1
    clear = (labels >= 0) & (minimum_filter(labels, window, mode="constant", cval=-1) == labels)
    clear &= maximum_filter(labels, window, mode="constant", cval=-1) == labels
    inner = np.zeros(int(pieces.max()) + 1, dtype=bool)
    outer = np.zeros_like(inner)
    for ahead, behind in (
        ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
        ((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
    ):
        cross = clear[behind] & clear[ahead] & (labels[behind] == labels[ahead]) & (band[behind] != band[ahead])
        for low, high in ((behind, ahead), (ahead, behind)):
            here = cross & (band[low] < band[high])
            outer[pieces[low][here & (band[low] < rings)]] = True
            inner[pieces[high][here]] = True
    return inner, outer
