"""How much of each ring a scan recovered, and how well, against the bench's ground truth."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from rig.evaluate.distances import root_mean_square
from rig.opened_rig import PixelTruth
from rig.pipeline import PairResult

# A true ring crossing counts as recovered when a kept point of the same ring lies this close (pixels).
_RECOVERED_WITHIN_PX = 1.0
# Neighbouring pixels whose true points lie farther apart than this are on two surfaces: no crossing.
_SAME_SURFACE_MM = 2.0
# Rings with less visible length than this (pixels) are too short to judge alone.
_MIN_RING_LENGTH_PX = 50.0
_STRIP_ROWS = 64  # rows of the truth taken at a time


def true_ring_crossings(
    truth: PixelTruth,
    radii: np.ndarray,
    center: tuple[float, float],
    shown: tuple[float, float, float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each ring truly crosses the camera image on lit, visible surface (and, with `shown`,
    where the projector shows its edge whole: u, v bounds, RingSamples.shown_within_px): sub-pixel positions
    (N, 2), ring index (N,) and the length of ring each crossing stands for (N,), pixels. Like the
    decoder, crossings are taken between vertical neighbours where the ring runs more across columns,
    between horizontal ones elsewhere, so one crossing stands for 1 / max(|cos|, |sin|) of length.
    A band of rows at a time (_STRIP_ROWS, with a row either side for the gradient and the vertical
    pairs), in the order of the bands: over the whole image at once, the float64 temporaries came
    to 10x the scan's frames."""
    height = truth.hit.shape[0]
    found: tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]] = ([], [], [])
    for top in range(0, height, _STRIP_ROWS):
        _strip_crossings(truth, radii, center, shown, slice(top, min(top + _STRIP_ROWS, height)), found)
    xy, ring, weight = found
    if not xy:
        return np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(xy), np.concatenate(ring), np.concatenate(weight)


def _strip_crossings(
    truth: PixelTruth,
    radii: np.ndarray,
    center: tuple[float, float],
    shown: tuple[float, float, float, float] | None,
    rows: slice,
    found: tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]],
) -> None:
    """true_ring_crossings from the pixels of `rows` and their pairs with the pixel below or to the
    right, appended to `found` (positions, ring indices, lengths)."""
    height = truth.hit.shape[0]
    lo, hi = max(rows.start - 1, 0), min(rows.stop + 1, height)  # a row either side, inside the image
    u, v = truth.projector_uv[lo:hi, :, 0], truth.projector_uv[lo:hi, :, 1]
    rho = np.hypot(u - center[0], v - center[1])
    seen = truth.hit[lo:hi] & truth.lit[lo:hi]
    if shown is not None:
        seen &= (u >= shown[0]) & (u <= shown[1]) & (v >= shown[2]) & (v <= shown[3])
    gy, gx = np.gradient(np.where(seen, rho, np.nan))  # the image's own one-sided ends only at its edges
    own = slice(rows.start - lo, rows.stop - lo)
    gy, gx = gy[own], gx[own]
    steep = np.abs(gy) >= np.abs(gx)
    length = np.hypot(gx, gy) / np.maximum(np.abs(gx), np.abs(gy))
    points = truth.points[lo:hi]
    down = min(rows.stop, height - 1) - rows.start  # rows with a row below them
    for axis in (0, 1):
        if axis == 0:
            a = (slice(own.start, own.start + down), slice(None))
            b = (slice(own.start + 1, own.start + 1 + down), slice(None))
            facing, weights = steep[:down], length[:down]
        else:
            a, b = (own, slice(None, -1)), (own, slice(1, None))
            facing, weights = ~steep[:, :-1], length[:, :-1]
        r1, r2 = rho[a], rho[b]
        same = np.linalg.norm(points[a] - points[b], axis=-1) < _SAME_SURFACE_MM
        usable = seen[a] & seen[b] & same & facing & np.isfinite(weights)
        low, high = np.minimum(r1, r2), np.maximum(r1, r2)
        first = np.searchsorted(radii, low[usable], side="right")  # the rings between the two radii
        last = np.searchsorted(radii, high[usable], side="right")
        r, c = np.nonzero(usable)
        for k in range(int(np.max(last - first, initial=0))):  # usually at most one ring per pixel pair
            has = last - first > k
            rk, ck, index = r[has], c[has], (first + k)[has]
            t = (radii[index] - r1[rk, ck]) / (r2[rk, ck] - r1[rk, ck])
            found[0].append(
                np.column_stack([ck + (t if axis == 1 else 0.0), rk + rows.start + (t if axis == 0 else 0.0)])
            )
            found[1].append(index)
            found[2].append(weights[rk, ck])


def ring_coverage_on_bench(pair: PairResult, truth: PixelTruth, dist: np.ndarray) -> dict[str, float | int | None]:
    """Ring coverage against the truth (overall and the least of any ring, by length) and the
    accuracy of the former wedges (points where the ring runs within acos(min_cos_beta) of the
    epipolar line, which the radius alone cannot place) against the rest; `dist` are the kept
    points' distances to the true surface."""
    rings, samples = pair.rings, pair.correspondence.samples
    assert rings is not None and samples is not None and samples.ring_radii_px is not None
    xy, ring, length = true_ring_crossings(truth, samples.ring_radii_px, samples.center_px, samples.shown_within_px)
    kept = rings.kept
    spread = 10.0 * (truth.hit.shape[0] + truth.hit.shape[1])  # rings far apart in the search
    found = cKDTree(np.column_stack([rings.camera_xy[kept], rings.ring[kept] * spread]))
    gap, _ = found.query(np.column_stack([xy, ring * spread]), distance_upper_bound=2 * _RECOVERED_WITHIN_PX)
    covered = gap <= _RECOVERED_WITHIN_PX
    visible = np.bincount(ring, weights=length, minlength=len(samples.ring_radii_px))
    recovered = np.bincount(ring, weights=length * covered, minlength=len(visible))
    judged = visible >= _MIN_RING_LENGTH_PX
    wedge = rings.cos_beta[kept] < samples.min_cos_beta

    def rms(part: np.ndarray) -> float | None:
        return root_mean_square(dist[part]) if part.any() else None

    return {
        "ring_coverage": float(recovered.sum() / max(1e-9, visible.sum())),
        "ring_coverage_min": float(np.min(recovered[judged] / visible[judged])) if judged.any() else None,
        "wedge_points": int(wedge.sum()),
        "wedge_rms_mm": rms(wedge),
        "outside_wedge_rms_mm": rms(~wedge),
    }
