"""The surface between the rings (dissertation ch.4-5): from ring samples alone, a depth map on the
camera grid and a mesh, interpolated between neighbouring rings, with holes where the rings say
there is no surface.

The samples are triangulated in the camera image (Delaunay). A triangle is kept only if it joins
one ring to the next (a ring missing between two others is a shadow or an occlusion: a hole), does
not bridge a gap along a ring, and is not seen edge-on or bent against its corners' normals (a
depth edge). Each camera pixel inside a kept triangle gets a point on its ray:

- `linear`: where the ray meets the triangle's plane;
- `quadratic`: the mean of that and the blend of the corners' tangent planes (each met by the ray,
  weighted by the point's barycentric coordinates). For a quadratic surface the linear
  interpolant errs by +1/2 sum b_i (x - x_i)' H (x - x_i) and the tangent blend by exactly the
  opposite, so their mean is exact to second order: only the corners' normals are needed;
- `cubic`: SciPy's Clough-Tocher C1 interpolant of camera depth over the image (gradients
  estimated globally, so they also feel samples across a depth edge).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from scipy.interpolate import CloughTocher2DInterpolator

from rig.geometry import CameraModel
from rig.kernels import kept_rows
from rig.lazy import lazy_module
from rig.pipeline.disc_fill import disc_points
from rig.pipeline.fill import fill_candidates, fill_points
from rig.pipeline.normals import crease_normals
from rig.pipeline.raster import FaceTerms, points_on_faces, rasterize, settled_pixels
from rig.pipeline.ring_faces import RingTriangles, ring_triangles
from rig.pipeline.surface_settings import SurfaceSettings
from rig.workers import POOL_WAIT_S, batches, full_on_pool, pool

surface_kernels = lazy_module("rig.kernels.ring_surface")  # numba compiles on first use

Interpolant = Literal["linear", "quadratic", "cubic"]
INTERPOLANTS: tuple[str, ...] = ("linear", "quadratic", "cubic")


@dataclass(frozen=True, eq=False)
class RingBands:
    """What the ring codec read at every camera pixel (rig.patterns.rings): the annulus between two
    rings (-1 unread) and the coarse polar angle (NaN unread), with the rings' radii and centre."""

    annulus: np.ndarray  # (H, W) int16
    angle: np.ndarray  # (H, W) float32, radians
    radii_px: np.ndarray  # (K,)
    center_px: tuple[float, float]


@dataclass(frozen=True, eq=False)
class RingSurface:
    """The interpolated surface of one (projector, camera) pair."""

    vertices: np.ndarray  # (M, 3) the ring samples
    normals: np.ndarray  # (M, 3) unit, toward the camera
    faces: np.ndarray  # (F, 3) kept triangles of the samples
    grid: np.ndarray  # (H, W, 3) float32, a point per covered pixel, NaN elsewhere (as the cloud holds them)
    valid: np.ndarray  # (H, W)
    counts: dict[str, int]
    ring: np.ndarray  # (M,) each sample's ring
    triangle: np.ndarray  # (H, W) int32: the face each covered pixel lies in, -1 elsewhere
    colour: np.ndarray | None = None  # (H, W, 3) float32 RGB in [0, 1] between the rings (rig.pipeline.colour)
    flank: np.ndarray | None = None  # (F,) bool: faces steep to both devices, kept as a flank (rig.pipeline.flanks)


def interpolate_surface(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    lit: np.ndarray | None = None,
    method: Interpolant = "quadratic",
    settings: SurfaceSettings | None = None,
    bands: RingBands | None = None,
    tri: np.ndarray | None = None,
) -> RingSurface:
    """The dense surface of one pair's kept ring samples (points, sub-pixel camera positions, ring
    index) by `method` (module docstring). `lit` (H, W): the pixels the projector lights (a triangle
    over dark ones spans a shadow). With `bands`, a pixel whose point the projector would light outside
    the annulus or angle that pixel read is a hole: its triangle bridges an edge its corners miss."""
    settings = settings or SurfaceSettings()
    surface = faces_surface(points, xy, ring, camera, projector, lit, method, settings, bands, tri)
    return fill_surface(surface, xy, camera, projector, lit, bands, settings)


def faces_surface(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    lit: np.ndarray | None = None,
    method: Interpolant = "quadratic",
    settings: SurfaceSettings | None = None,
    bands: RingBands | None = None,
    tri: np.ndarray | None = None,
    directions: np.ndarray | None = None,
) -> RingSurface:
    """interpolate_surface's surface on the triangles alone, before the pixels beyond them are
    filled (fill_surface). `tri`, `directions`: the samples' Delaunay triangles and camera rays,
    where known."""
    check_interpolant(method)
    settings = settings or SurfaceSettings()
    faces = covered_faces(points, xy, ring, camera, projector, lit, settings, tri, directions)
    return surface_on_faces(points, xy, ring, faces, camera, projector, method, settings, bands)


def check_interpolant(method: str) -> None:
    """ValueError naming `method` unless it is one of INTERPOLANTS."""
    if method not in INTERPOLANTS:
        raise ValueError(f"unknown interpolant {method!r}; known: {', '.join(INTERPOLANTS)}")


@dataclass(frozen=True, eq=False)
class CoveredFaces:
    """The kept triangles of a pair's ring samples and the camera pixels they cover (covered_faces).
    Its pixel lists take 8 bytes a covered pixel: dropped once the points are found
    (surface_on_faces), the fill's peak of memory holds none."""

    triangles: RingTriangles
    pixels: tuple[np.ndarray, np.ndarray]  # flat pixels and their faces (rig.pipeline.raster.rasterize)
    counts: dict[str, int]


def covered_faces(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    lit: np.ndarray | None,
    settings: SurfaceSettings,
    tri: np.ndarray | None = None,
    directions: np.ndarray | None = None,
) -> CoveredFaces:
    """faces_surface's triangles, those over a shadow dropped, and their pixels: all that is known
    of the surface before its points."""
    triangles = ring_triangles(points, xy, ring, camera, projector, settings, tri, directions)
    counts = triangles.counts
    pixel, owner, kept = rasterize(xy, triangles.tri, camera.width, camera.height, lit, settings.max_unlit)
    if lit is not None:  # triangles over a shadow dropped
        counts["dropped_shadow"] = int(len(kept) - kept.sum())
        counts["faces"] -= counts["dropped_shadow"]
        if not kept.all():
            triangles = triangles.subset(kept)
    return CoveredFaces(triangles, (pixel, owner), counts)


def surface_on_faces(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    faces: CoveredFaces,
    camera: CameraModel,
    projector: CameraModel,
    method: Interpolant,
    settings: SurfaceSettings,
    bands: RingBands | None,
) -> RingSurface:
    """faces_surface from its faces (covered_faces): each covered pixel's point."""
    check_interpolant(method)
    triangles, counts = faces.triangles, faces.counts
    tri, normals = triangles.tri, triangles.normals
    grid, ok, agree = _points_in_faces(points, xy, triangles, camera, projector, faces.pixels, method, bands, settings)
    # pixels off their bands, and every pixel of a face with many (it bridges an edge); the pixels
    # as images then (CoveredFaces)
    tested = len(tri) if bands is not None else 0
    valid, triangle, dropped = settled_pixels(faces.pixels, (ok, agree), tested, settings.max_band_disagreement, grid)
    if bands is not None:
        counts["dropped_band_px"] = dropped
    counts["pixels"] = int(np.count_nonzero(ok))
    del ok, agree
    shape = (camera.height, camera.width)
    return RingSurface(
        points, normals, tri, grid.reshape(*shape, 3), valid.reshape(shape), counts, ring, triangle.reshape(shape),
        flank=triangles.flank,
    )  # fmt: skip


def fill_surface(
    surface: RingSurface,
    xy: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    lit: np.ndarray | None,
    bands: RingBands | None,
    settings: SurfaceSettings,
) -> RingSurface:
    """faces_surface's `surface` (its samples' image positions `xy`) with the pixels beyond its
    triangles filled where a point in their own band is found (rig.pipeline.fill): its grid and valid
    image in place, its counts anew."""
    if bands is None or not settings.fill:
        return surface
    valid, grid = surface.valid.reshape(-1), surface.grid.reshape(-1, 3)  # views: written in place
    found = (surface.vertices, surface.normals, xy, surface.ring, surface.faces)
    filled = _filled(*found, camera, projector, valid, lit, bands, grid, settings)
    valid[filled] = True
    counts = {k: v for k, v in surface.counts.items() if k != "pixels"}  # in their order, pixels last
    counts["filled_px"], counts["pixels"] = len(filled), surface.counts["pixels"] + len(filled)
    return replace(surface, counts=counts)


def _points_in_faces(
    points: np.ndarray,
    xy: np.ndarray,
    triangles: RingTriangles,
    camera: CameraModel,
    projector: CameraModel,
    pixels: tuple[np.ndarray, np.ndarray],
    method: Interpolant,
    bands: RingBands | None,
    settings: SurfaceSettings,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The flat camera grid (H*W, 3) float32 with each pixel's point on its face (pixels: flat pixels and
    their faces, rasterize's) by `method`, NaN elsewhere; per pixel whether a point was found, and
    (with `bands`) whether it lies in the band its pixel read. Batches of pixels on the pool."""
    pixel, owner = pixels
    tri = triangles.tri
    corners = (
        crease_normals(tri, triangles.normals, triangles.face, triangles.weight) if method == "quadratic" else None
    )
    common_origin = camera.center if camera.projection != "orthographic" else None
    terms = FaceTerms.of(points, xy, tri, corners, common_origin)
    del corners  # in the terms now: 5 MB fewer at the surface's peak, the grid's filling
    grid = full_on_pool((camera.height * camera.width, 3), np.nan, np.float32)
    ok = np.ones(len(pixel), dtype=bool)
    agree = np.ones(len(pixel), dtype=bool)

    def solve(span: tuple[int, int]) -> None:  # each batch writes its own pixels
        part = pixel[span[0] : span[1]]
        if method == "cubic":
            origins, directions = (np.asarray(rays[part]) for rays in camera.pixel_rays)
            found = origins + _cubic_depth(points, xy, camera, part)[:, None] * directions
            grid[part] = found
            ok[span[0] : span[1]] = np.isfinite(found).all(axis=1)
        else:  # straight into the grid
            found_at = (grid, part, ok[span[0] : span[1]])
            points_on_faces(terms, part, owner[span[0] : span[1]], camera.pixel_rays, camera.width, found_at)
        if bands is not None:
            agree[span[0] : span[1]] = band_agreement(grid, part, projector, bands, settings, rows=part)

    # cubic: one interpolant over the whole image, not one per batch
    list(pool().map(solve, [(0, len(pixel))] if method == "cubic" else batches(len(pixel))))
    return grid, ok, agree


def _filled(
    points: np.ndarray,
    normals: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    tri: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    mask: np.ndarray,
    lit: np.ndarray | None,
    bands: RingBands,
    grid: np.ndarray,
    settings: SurfaceSettings,
) -> np.ndarray:
    """The pixels beyond the triangles (`mask`: flat, the pixels they cover) given a point in their
    own band (rig.pipeline.fill); their points are written into `grid` (flat)."""
    candidate = fill_candidates(mask, bands.annulus, lit)
    in_triangle = np.bincount(tri.ravel(), minlength=len(points)) > 0
    annulus = bands.annulus.ravel()[candidate].astype(np.int64)
    # an inner disc the rings close around, on the pool (one thread's work) beside the fill of every
    # candidate; a pixel's fill does not depend on which others are filled with it
    disc = pool().submit(disc_points, grid, mask, candidate, annulus, camera)
    samples = kept_rows(in_triangle, points, normals, xy, ring)
    found = fill_points(*samples, camera, candidate, annulus, settings.fill_settings)
    in_disc = disc.result(timeout=POOL_WAIT_S)
    inside = np.isfinite(in_disc).all(axis=1)  # the disc's points before the fill's
    found[inside] = in_disc[inside]
    keep = np.isfinite(found).all(axis=1)
    found, filled = kept_rows(keep, found, candidate)
    agree = band_agreement(found, filled, projector, bands, settings)
    found, filled = kept_rows(agree, found, filled)
    grid[filled] = found
    return filled


def band_agreement(
    found: np.ndarray,
    pixel: np.ndarray,
    projector: CameraModel,
    bands: RingBands,
    settings: SurfaceSettings,
    rows: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each interpolated point (at flat camera pixel `pixel`; found[n], or found[rows[n]]
    where `found` is a flat camera grid) projects into the annulus and near the polar angle its
    pixel read; unread pixels agree with anything, a NaN point with nothing.
    Near the rings' centre the polar angle says little (and is read poorly): it is not checked there
    (rig.kernels.ring_surface, which does it in one compiled loop)."""
    agree = np.empty(len(pixel), dtype=bool)
    device = tuple(np.ascontiguousarray(a, np.float64) for a in (projector.R, projector.t, projector.K, projector.dist))
    kind = (projector.projection == "orthographic", projector.has_distortion)
    centre = (float(bands.center_px[0]), float(bands.center_px[1]))
    read = (bands.annulus.ravel(), bands.angle.ravel(), np.asarray(bands.radii_px, np.float64), *centre)
    margins = (float(settings.band_margin_px), float(settings.band_angle_rad))
    rows = np.arange(len(pixel)) if rows is None else rows
    # the points in their own float type (the grid's float32): a float64 copy of a grid would be of
    # the whole grid, for every batch
    points = (np.ascontiguousarray(found), rows)
    surface_kernels.band_agreement(points, pixel, device, kind, read, margins, agree, 0, len(pixel))
    return agree


def _cubic_depth(points: np.ndarray, xy: np.ndarray, camera: CameraModel, pixel: np.ndarray) -> np.ndarray:
    """Distance along each pixel's ray by Clough-Tocher over the image, from the samples' distances."""
    distance = np.linalg.norm(points - camera.center, axis=1)
    interpolant = CloughTocher2DInterpolator(xy, distance)
    query = np.column_stack([pixel % camera.width, pixel // camera.width]).astype(np.float64)
    return np.asarray(interpolant(query), dtype=np.float64)
