"""The surface where no triangle between two rings reaches though rings enclose it: holes between two
rings where triangles were dropped, and the inner disc inside the innermost ring where that ring
does not close around it (where it does, rig.pipeline.disc_fill fills it across).

Such a pixel has read its annulus (between rings a-1 and a, or inside ring 0), so its point lies
on its ray between those two rings' cones. Its neighbourhood is the ring samples near it in the
image, of those two rings only, on one surface (samples farther apart in space than a steep slope
allows for their distance in the image lie on two surfaces; the slope allowed grows as the nearest
sample turns from the camera, so that a limb turning away stays one surface). A quadratic height
field is fitted to their positions and normals (each sample gives a height and two slopes; a small
ridge on the bends leaves a tangent plane where a single straight ring cannot show a bend across
it), and the pixel's ray meets it. The point is kept only if it lies in the pixel's own annulus and
near the polar angle it read (rig.pipeline.surface.band_agreement). Where samples of two surfaces
both reach a pixel (the gap at a depth step, between the last ring on one side and the first on the
other) nothing says on which side of the step the pixel lies: it stays a hole, and is reported as
one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from rig.geometry import CameraModel
from rig.lazy import lazy_module
from rig.workers import batches, pool

fill_kernels = lazy_module("rig.kernels.fill")  # numba compiles on first use

_CHUNK = 16_384  # candidate pixels fitted at a time (a few MB per (N, k, 3) array)


@dataclass(frozen=True)
class FillSettings:
    neighbours: int = 16  # ring samples near a pixel considered for its fit, half from each of its rings
    reach_px: float = 48.0  # no pixel farther than this from a sample of its rings is filled
    min_samples: int = 4  # samples on the pixel's surface a fit needs
    steep_stretch: float = 3.0  # samples this many footprints apart per pixel of image lie on two surfaces ...
    min_facing: float = 0.25  # ... footprints stretched by 1 / cos(slant) of the nearest sample, to this at most
    bend_ridge: float = 0.05  # ridge on the bends, relative to the fit's own scale
    max_misfit_px: float = 2.0  # samples straying from their fit by more (rms, in footprints) span two surfaces


def fill_candidates(covered: np.ndarray, annulus: np.ndarray, lit: np.ndarray | None) -> np.ndarray:
    """Flat pixels that read an annulus, are lit and are not covered by a triangle."""
    candidate = ~covered.ravel() & (annulus.ravel() >= 0)
    if lit is not None:
        candidate &= lit.ravel()
    return np.flatnonzero(candidate)


def fill_points(
    points: np.ndarray,
    normals: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    pixel: np.ndarray,
    annulus: np.ndarray,
    settings: FillSettings,
) -> np.ndarray:
    """A point (N, 3) for each flat camera pixel `pixel` that reads `annulus` (N,), NaN where no
    neighbourhood on one surface of its two rings reaches it; from samples (points, unit normals
    toward the camera, sub-pixel image positions, ring indices) of triangles already kept."""
    found = np.full((len(pixel), 3), np.nan)
    if len(points) < settings.min_samples or len(pixel) == 0:
        return found
    near = _RingNeighbours(xy, ring)
    origins, directions = camera.pixel_rays
    for a in np.unique(annulus):
        bounding = (0,) if a == 0 else (int(a) - 1, int(a))
        if not all(r in near.trees for r in bounding):  # beyond a surface's last ring: nothing encloses it
            continue
        of_annulus = np.flatnonzero(annulus == a)
        positions = _positions(pixel[of_annulus], camera.width)
        if a > 0:  # most lie beyond a surface's last ring: one of their rings out of reach (cheap to ask)
            reached = near.reaches(positions, bounding, settings.reach_px)
            of_annulus, positions = of_annulus[reached], positions[reached]
        for start in range(0, len(of_annulus), _CHUNK):
            part = of_annulus[start : start + _CHUNK]
            at = pixel[part]
            query = positions[start : start + _CHUNK]
            dist, index = near.query(query, bounding, settings.neighbours, settings.reach_px)
            # most candidates lie beyond a surface's last ring: drop them before the costlier tests
            rows = np.flatnonzero(_enclosed(annulus[part], ring, index, np.isfinite(dist)))
            dist, index, ann = dist[rows], index[rows], annulus[part][rows]
            use = _one_surface(points, normals, xy, ring, camera, index, dist, ann, settings)
            use &= _enclosed(ann, ring, index, use)[:, None]
            enough = use.sum(axis=1) >= settings.min_samples
            if not enough.any():
                continue
            rays = (np.asarray(origins[at[rows[enough]]]), np.asarray(directions[at[rows[enough]]]))
            met, misfit_mm = _fit_and_meet(points, normals, index[enough], use[enough], rays, settings)
            smooth = misfit_mm <= settings.max_misfit_px * camera.mm_per_px(np.nan_to_num(met))
            found[part[rows[enough][smooth]]] = met[smooth]
    return found


class _RingNeighbours:
    """The samples of each ring, searchable by image position: a pixel's neighbourhood takes an equal
    share from each of its two rings, however much closer one of them runs (at a limb, or where one
    ring ends, the nearest samples of all would be of one ring only)."""

    def __init__(self, xy: np.ndarray, ring: np.ndarray) -> None:
        order = np.argsort(ring, kind="stable")
        rings, starts = np.unique(ring[order], return_index=True)
        self.members = dict(zip(rings.tolist(), np.split(order, starts[1:]), strict=True))
        self.trees = {r: cKDTree(xy[m]) for r, m in self.members.items()}
        self.tree, self.ring = cKDTree(xy), ring

    def reaches(self, at: np.ndarray, rings: tuple[int, ...], reach: float) -> np.ndarray:
        """(N,) whether a sample of each of `rings` lies within `reach` of each position: what a
        pixel between two rings needs to be enclosed by them (_enclosed)."""
        ok = np.ones(len(at), dtype=bool)
        for r in rings:
            dist, _ = self.trees[r].query(at, k=1, distance_upper_bound=reach, workers=-1)
            ok &= np.isfinite(dist)
        return ok

    def query(self, at: np.ndarray, rings: tuple[int, ...], k: int, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2k) distances (inf beyond `reach`, or for a sample listed already) and sample indices
        (0 there) of each position's `k` nearest samples of any ring, then of `rings`' (k / len(rings)
        each): the first tell whether another surface is in reach, the others join the fit."""
        k = min(k, len(self.ring))
        dist, index = self.tree.query(at, k=k, distance_upper_bound=reach, workers=-1)
        dists, indices = [dist.reshape(len(at), k)], [index.reshape(len(at), k)]
        for r in rings:
            members = self.members[r]
            n = min(k // len(rings), len(members))
            dist, index = self.trees[r].query(at, k=n, distance_upper_bound=reach, workers=-1)
            dist, index = dist.reshape(len(at), n), members[np.minimum(index, len(members) - 1)].reshape(len(at), n)
            dist[(index[:, :, None] == indices[0][:, None, :]).any(axis=2)] = np.inf  # among the nearest already
            dists.append(dist)
            indices.append(index)
        dist, index = np.concatenate(dists, axis=1), np.concatenate(indices, axis=1)
        return dist, np.where(np.isfinite(dist), index, 0)


def _positions(pixel: np.ndarray, width: int) -> np.ndarray:
    """(N, 2) image positions (x, y) of flat pixels."""
    return np.column_stack([pixel % width, pixel // width]).astype(np.float64)


def _one_surface(
    points: np.ndarray,
    normals: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    index: np.ndarray,
    dist: np.ndarray,
    annulus: np.ndarray,
    settings: FillSettings,
) -> np.ndarray:
    """(N, k) which neighbours a pixel's fit uses: samples of its two rings, on the surface of its
    nearest such sample; none at all where any sample in reach (of any ring) lies on another surface."""
    reached = np.isfinite(dist)
    safe = np.where(reached, index, 0)
    near = points[safe]  # (N, k, 3)
    rings = ring[safe]
    bounding = reached & ((rings == annulus[:, None]) | (rings == annulus[:, None] - 1))
    first = np.argmin(np.where(bounding, dist, np.inf), axis=1)  # the nearest of them
    rows = np.arange(len(index))
    reference = near[rows, first]
    ref_xy = xy[safe[rows, first]]
    # a surface turned away from the camera stretches over fewer pixels: the reference's slant says how much
    orthographic = camera.projection == "orthographic"
    to_camera = np.broadcast_to(-camera.axis, reference.shape) if orthographic else camera.center - reference
    facing = np.abs(np.einsum("ij,ij->i", normals[safe[rows, first]], to_camera)) / np.linalg.norm(to_camera, axis=1)
    footprint = camera.mm_per_px(reference) / np.maximum(facing, settings.min_facing)
    apart_px = np.linalg.norm(xy[safe] - ref_xy[:, None, :], axis=2)
    apart_mm = np.linalg.norm(near - reference[:, None, :], axis=2)
    same = apart_mm <= settings.steep_stretch * footprint[:, None] * (apart_px + 1.0)
    contested = (reached & ~same).any(axis=1) | ~bounding.any(axis=1)
    return bounding & same & ~contested[:, None]


def _enclosed(annulus: np.ndarray, ring: np.ndarray, index: np.ndarray, use: np.ndarray) -> np.ndarray:
    """(N,) pixels their samples enclose: inside the innermost ring (annulus 0, which the decode
    read), or with samples of both rings of their annulus around them. A pixel that sees only one of
    its rings lies beyond a surface's last ring: extrapolating there (a limb the projector grazes)
    errs by far more than interpolating does, and it is left a hole."""
    rings = ring[index]
    inner = (use & (rings == annulus[:, None] - 1)).any(axis=1)
    outer = (use & (rings == annulus[:, None])).any(axis=1)
    return (annulus == 0) | (inner & outer)


def _fit_and_meet(
    points: np.ndarray,
    normals: np.ndarray,
    index: np.ndarray,
    use: np.ndarray,
    rays: tuple[np.ndarray, np.ndarray],
    settings: FillSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, the weighted quadratic height field of its used samples (positions and slopes, in a
    frame along their mean normal: rig.kernels.fill) met by its ray (origins, unit directions), NaN
    where it misses; and the rms of the samples' heights off the fit (mm). Samples of two levels
    joined by a step fit a ramp between them, which their own slopes contradict: the heights stray
    by millimetres."""
    count = len(index)
    coef, frame = np.empty((count, 6)), np.empty((count, 3, 3))
    origin, misfit = np.empty((count, 3)), np.empty(count)
    arrays = (np.ascontiguousarray(points, np.float64), np.ascontiguousarray(normals, np.float64))
    index, use = np.ascontiguousarray(index, np.int64), np.ascontiguousarray(use, np.bool_)

    def fit(span: tuple[int, int]) -> None:
        fill_kernels.fit_height_fields(*arrays, index, use, settings.bend_ridge, coef, frame, origin, misfit, *span)

    list(pool().map(fit, batches(count)))
    return _meet(coef, frame, origin, rays), misfit


def _meet(coef: np.ndarray, frame: np.ndarray, origin: np.ndarray, rays: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Where each ray meets its height field h(x, y) = c0 + c1 x + c2 y + c3 x^2 + c4 x y + c5 y^2:
    the root of a quadratic in the distance along the ray nearest the tangent plane's."""
    a = np.einsum("nij,nj->ni", frame, rays[0] - origin)
    b = np.einsum("nij,nj->ni", frame, rays[1])
    c0, c1, c2, c3, c4, c5 = coef.T
    quad = c3 * b[:, 0] ** 2 + c4 * b[:, 0] * b[:, 1] + c5 * b[:, 1] ** 2
    lin = c1 * b[:, 0] + c2 * b[:, 1] + 2 * c3 * a[:, 0] * b[:, 0] + c4 * (a[:, 0] * b[:, 1] + a[:, 1] * b[:, 0])
    lin += 2 * c5 * a[:, 1] * b[:, 1] - b[:, 2]
    const = c0 + c1 * a[:, 0] + c2 * a[:, 1] + c3 * a[:, 0] ** 2 + c4 * a[:, 0] * a[:, 1] + c5 * a[:, 1] ** 2 - a[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        plane = -const / lin
        root = np.sqrt(lin**2 - 4 * quad * const)
        t1, t2 = (-lin + root) / (2 * quad), (-lin - root) / (2 * quad)
    nearer = np.where(np.abs(t1 - plane) < np.abs(t2 - plane), t1, t2)
    t = np.where(np.abs(quad) * np.abs(plane) ** 2 < 1e-9 * np.abs(const) + 1e-12, plane, nearer)
    t = np.where(np.isfinite(t) & (t > 0), t, np.nan)
    return rays[0] + t[:, None] * rays[1]
