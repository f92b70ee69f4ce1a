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

from collections.abc import Callable

import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter

from rig.evaluate.regions import MIN_REGION_SHARE, joined_labels, region_kernels
from rig.workers import point_blocks

SECTOR_ARC_PX = 8.0  # projector pixels of arc, at its outer ring, of each sector of an annulus
CLEAR_PX = 2  # a ring is seen where it crosses surface this many camera pixels clear of its edge
BAND_ROWS = 64  # image rows worked out at once


# A band of rows' projector polar coordinates (rho, theta) about the rings' centre, NaN where none
PolarRows = Callable[[slice], tuple[np.ndarray, np.ndarray]]


def between_rings(
    polar: PolarRows,
    region: np.ndarray,
    area: np.ndarray,
    seen: np.ndarray,
    radii: np.ndarray,
) -> np.ndarray:
    """(H, W) the pixels a ring set (`radii`, increasing) promises a surface at (see the module
    docstring), of the regions (`region` labels, -1 none) that hold at least MIN_REGION_SHARE of
    the `seen` area; `polar` each pixel's projector polar coordinates about the rings' centre, a
    band of rows at a time (polar_rows, image_rows). Each pixel's annulus and sector are kept as
    int16 (int32 past 2**15 sectors): its polar coordinates and its cell's key (int64) were five
    image-sized arrays held together."""
    radii = np.asarray(radii, dtype=np.float64)
    labels = np.empty(seen.shape, np.int32)
    fits_int16 = len(radii) == 0 or max(len(radii), _most_sectors(radii)) < 2**15  # any projector's rings do
    band, sector = (np.empty(seen.shape, np.int16 if fits_int16 else np.int32) for _ in range(2))
    for rows in point_blocks(seen.shape[0], BAND_ROWS):
        rho, theta = polar(rows)
        labels[rows] = np.where(seen[rows] & np.isfinite(rho) & np.isfinite(theta), region[rows], -1)
        # radii[band-1] <= rho < radii[band]
        band[rows] = np.searchsorted(radii, np.nan_to_num(rho, nan=-1.0), side="right")
        if len(radii):
            sector[rows] = _sector(band[rows], theta, radii)
    most = int(labels.max(initial=-1))
    if most < 0 or len(radii) == 0:
        return np.zeros(seen.shape, dtype=bool)
    per_label = region_kernels.label_totals(labels.ravel(), area.ravel(), most + 1)
    judged = np.zeros(len(per_label), dtype=bool)
    judged[per_label >= MIN_REGION_SHARE * per_label.sum()] = True
    for rows in point_blocks(len(labels), BAND_ROWS):  # the regions not judged: no region
        part = labels[rows]
        part[(part >= 0) & ~judged[np.maximum(part, 0)]] = -1
    pieces = _pieces(labels, band, sector, radii)
    del sector  # not needed for the pieces' bounds
    inner, outer = _bounded(band, labels, pieces, len(radii))
    piece = pieces[labels >= 0]
    ok = outer[piece] & (inner[piece] | (band[labels >= 0] == 0))  # the disc needs its ring only
    target = np.zeros(seen.shape, dtype=bool)
    target[labels >= 0] = ok
    return target


def polar_rows(uv: np.ndarray, center: tuple[float, float]) -> PolarRows:
    """The polar coordinates about `center` of projector coordinates `uv` (H, W, 2), made as a band
    of rows is asked for."""

    def band(rows: slice) -> tuple[np.ndarray, np.ndarray]:
        u, v = _offsets(uv[rows], center)
        return np.hypot(u, v), np.arctan2(v, u)

    return band


class ProjectorRadius:
    """polar_rows' rho (float64), made only where asked for: no image of it (10 MB at 1280x1024)."""

    def __init__(self, uv: np.ndarray, center: tuple[float, float]) -> None:
        self.uv, self.center, self.shape = uv, center, uv.shape[:2]

    def __call__(self, y: np.ndarray, x: np.ndarray) -> np.ndarray:
        """rho at the pixels (y, x)."""
        return np.hypot(*_offsets(self.uv[y, x], self.center)).astype(np.float64, copy=False)

    def within(self, radius: float) -> np.ndarray:
        """(H, W) whether rho is under `radius`, a band of rows at a time."""
        inside = np.empty(self.shape, bool)
        for rows in point_blocks(len(inside), BAND_ROWS):
            inside[rows] = np.hypot(*_offsets(self.uv[rows], self.center)).astype(np.float64, copy=False) < radius
        return inside


def _offsets(uv: np.ndarray, center: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Projector coordinates (..., 2) less `center`: u and v."""
    return uv[..., 0] - center[0], uv[..., 1] - center[1]


def image_rows(rho: np.ndarray, theta: np.ndarray) -> PolarRows:
    """Polar coordinates held as images (H, W), a band of rows at a time."""
    return lambda rows: (rho[rows], theta[rows])


def _sector(band: np.ndarray, theta: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Each pixel's sector of its annulus (`band`): each annulus is cut into sectors of
    SECTOR_ARC_PX of arc at its outer ring (the band beyond the last ring into one)."""
    outer = radii[np.minimum(band, len(radii) - 1)]
    sectors = np.maximum(8, np.ceil(2 * np.pi * outer / SECTOR_ARC_PX)).astype(np.int64)
    sector = np.floor((np.nan_to_num(theta) + np.pi) / (2 * np.pi) * sectors).astype(np.int64) % sectors
    sector[band >= len(radii)] = 0
    return sector


def _pieces(labels: np.ndarray, band: np.ndarray, sector: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(H, W) a label per connected piece (4-neighbours) of the pixels of one region (`labels` >= 0),
    annulus and sector; their joins a band of rows at a time, from each cell's key (int64)."""
    height = labels.shape[0]
    right = np.empty((height, max(labels.shape[1] - 1, 0)), bool)
    down = np.empty((max(height - 1, 0), labels.shape[1]), bool)
    for rows in point_blocks(height, BAND_ROWS):
        below = slice(rows.start, min(rows.stop + 1, height))  # and the next band's first row
        key = _key(labels[below], band[below], sector[below], radii)
        ahead = key[: rows.stop - rows.start]
        right[rows] = (ahead[:, :-1] >= 0) & (ahead[:, :-1] == ahead[:, 1:])
        down[rows.start : below.stop - 1] = (key[:-1] >= 0) & (key[:-1] == key[1:])
    return joined_labels(right, down, np.ones(labels.shape, bool)).reshape(labels.shape)


def _key(labels: np.ndarray, band: np.ndarray, sector: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """A key per pixel for its (region, annulus, sector), -1 for a pixel of no region."""
    key = (labels.astype(np.int64) * (len(radii) + 1) + band) * _most_sectors(radii) + sector
    key[labels < 0] = -1
    return key


def _most_sectors(radii: np.ndarray) -> int:
    """The sectors of any annulus, at most (_sector)."""
    return int(np.ceil(2 * np.pi * radii[-1] / SECTOR_ARC_PX)) + 8


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
