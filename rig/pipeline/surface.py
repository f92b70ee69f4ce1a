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

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.interpolate import CloughTocher2DInterpolator

from rig.geometry import CameraModel
from rig.kernels import kept_rows
from rig.lazy import lazy_module
from rig.pipeline.disc_fill import disc_points
from rig.pipeline.fill import FillSettings, fill_candidates, fill_points
from rig.pipeline.flanks import grown_flanks
from rig.pipeline.normals import (
    crease_normals,
    ring_pairs,
    smoothed_normals,
    vertex_normals,
)
from rig.pipeline.raster import FaceTerms, points_on_faces, rasterize, settled_pixels
from rig.pipeline.triangulation import delaunay
from rig.workers import batches, full, pool

normal_kernels = lazy_module("rig.kernels.normals")  # numba compiles on first use
triangle_kernels = lazy_module("rig.kernels.triangles")
surface_kernels = lazy_module("rig.kernels.ring_surface")

Interpolant = Literal["linear", "quadratic", "cubic"]
INTERPOLANTS: tuple[str, ...] = ("linear", "quadratic", "cubic")

_BRIDGE_ROUNDS = 4  # rounds of dropping triangles bent off their corners (ring_triangles)
_PAIRS_TIMEOUT_S = 300.0  # a bound on waiting for the pool, far beyond the ~30 ms it takes


@dataclass(frozen=True)
class SurfaceSettings:
    max_gap_px: float = 6.0  # two samples of one ring further apart than this are not neighbours
    max_slant_deg: float = 84.0  # triangles seen more edge-on than this span a depth edge
    max_bend_deg: float = 50.0  # ... as do triangles this far from one of their corners' normals
    max_bend_excess_deg: float = 20.0  # ... and those bent this much more from their corners than they differ
    min_foreshortening: float = 0.15  # ... and edges steep to both devices (rig.pipeline.flanks) ...
    max_flank_turn_deg: float = 10.0  # ... unless they continue the surface beside them (rig.pipeline.flanks)
    max_unlit: float = 0.02  # triangles over more of their pixels dark than this span a shadow
    band_margin_px: float = 2.0  # a point may project this far outside the annulus its pixel read ...
    band_angle_rad: float = 0.15  # ... and this far from the polar angle it read (3x the code's p99.9)
    normal_smoothing_px: float = 4.0  # samples' normals averaged over their ring this far either way
    max_band_disagreement: float = 0.25  # a triangle with more of its pixels off their bands bridges an edge
    fill: bool = True  # fill the inner disc and holes the rings enclose (rig.pipeline.fill)
    fill_settings: FillSettings = field(default_factory=FillSettings)


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
    grid: np.ndarray  # (H, W, 3) a point per covered pixel, NaN elsewhere
    valid: np.ndarray  # (H, W)
    counts: dict[str, int]
    ring: np.ndarray  # (M,) each sample's ring
    triangle: np.ndarray  # (H, W) int32: the face each covered pixel lies in, -1 elsewhere
    colour: np.ndarray | None = None  # (H, W, 3) float32 RGB in [0, 1] between the rings (rig.pipeline.colour)
    flank: np.ndarray | None = None  # (F,) bool: faces steep to both devices, kept as a flank (rig.pipeline.flanks)


@dataclass(frozen=True, eq=False)
class RingTriangles:
    """The kept triangles of a pair's ring samples (ring_triangles)."""

    tri: np.ndarray  # (F, 3) sample indices
    face: np.ndarray  # (F, 3) unit normals, toward the camera
    weight: np.ndarray  # (F,) 1 / longest edge (rig.pipeline.normals.vertex_normals)
    normals: np.ndarray  # (M, 3) the samples' unit normals, toward the camera
    counts: dict[str, int]  # how many triangles each test dropped
    directions: np.ndarray  # (M, 3) the samples' camera rays
    pairs: np.ndarray  # (P, 2) samples of one ring whose normals are averaged (ring_pairs)
    flank: np.ndarray  # (F,) bool: steep to both devices, kept as a flank (rig.pipeline.flanks)

    def subset(self, keep: np.ndarray) -> RingTriangles:
        """These triangles but only those `keep` marks, the samples' normals from them alone (a
        dropped triangle bridged a step: its tilt is no part of either side's normal)."""
        tri, face, weight = self.tri[keep], self.face[keep], self.weight[keep]
        return RingTriangles(tri, face, weight, _normals(tri, face, weight, self.directions, self.pairs), self.counts,
                             self.directions, self.pairs, self.flank[keep])  # fmt: skip


def _normals(
    tri: np.ndarray, face: np.ndarray, weight: np.ndarray, directions: np.ndarray, pairs: np.ndarray
) -> np.ndarray:
    normals = vertex_normals(tri, face, weight, directions)
    in_triangle = np.bincount(tri.ravel(), minlength=len(directions)) > 0  # the others' normals are a guess
    return smoothed_normals(normals, pairs, in_triangle)


def ring_triangles(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    settings: SurfaceSettings,
    tri: np.ndarray | None = None,
) -> RingTriangles:
    """The kept triangles of the samples' image Delaunay triangulation `tri` (see the module docstring)."""
    directions = np.asarray(camera.rays(xy)[1])
    # the samples' neighbours along their rings need no triangles: found beside the triangulation
    neighbours = pool().submit(ring_pairs, points, xy, ring, settings.normal_smoothing_px)
    tri = delaunay(xy) if tri is None else tri
    tested = _tested(points, xy, ring, camera, projector, directions, tri, settings.max_gap_px)
    verdict, face, weight, slant, foreshortened = tested
    counts = {"triangles": len(tri)}
    verdicts = {"ring_skipped": triangle_kernels.RING_SKIPPED, "gap": triangle_kernels.GAP}
    for name, code in (*verdicts.items(), ("one_ring", triangle_kernels.ONE_RING)):
        counts[f"dropped_{name}"] = int((verdict == code).sum())
    keep = verdict == triangle_kernels.KEPT
    tri, face, weight, slant, foreshortened = kept_rows(keep, tri, face, weight, slant, foreshortened)
    edge_on = slant < np.cos(np.radians(settings.max_slant_deg))
    steep = ~edge_on & (foreshortened < settings.min_foreshortening)
    edge_on |= steep
    held = kept_rows(steep, tri, face, weight)  # a flank or a bridge: told apart once the rest is known
    tri, face, weight = kept_rows(~edge_on, tri, face, weight)
    normals = vertex_normals(tri, face, weight, directions)
    bent = normal_kernels.bent_from_corners(normals, tri, face, np.cos(np.radians(settings.max_bend_deg)))
    tri, face, weight = kept_rows(~bent, tri, face, weight)
    pairs = neighbours.result(timeout=_PAIRS_TIMEOUT_S)
    # corners' normals as the interpolant takes them (smoothed along the rings), without the
    # triangles dropped so far: a triangle that bridges a step stands out once its neighbours that
    # bridge it too are gone, so a few rounds
    dropped = int(edge_on.sum() + bent.sum())
    normals = _normals(tri, face, weight, directions, pairs)
    for _ in range(_BRIDGE_ROUNDS):
        again = _off_its_corners(normals, tri, face, settings.max_bend_excess_deg)
        if not again.any():
            break
        (tri, face, weight), dropped = kept_rows(~again, tri, face, weight), dropped + int(again.sum())
        normals = _normals(tri, face, weight, directions, pairs)
    flank = grown_flanks((tri, face, weight), held, directions, settings.max_flank_turn_deg)
    if flank.any():
        tri, face, weight = (np.concatenate([k, h[flank]]) for k, h in zip((tri, face, weight), held, strict=True))
        normals = _normals(tri, face, weight, directions, pairs)
    counts["kept_flank"] = int(flank.sum())
    counts["dropped_depth_edge"] = dropped - counts["kept_flank"]
    steep = np.concatenate([np.zeros(len(tri) - counts["kept_flank"], dtype=bool), np.ones(counts["kept_flank"], bool)])
    counts["faces"] = len(tri)
    return RingTriangles(tri, face, weight, normals, counts, directions, pairs, steep)


def _tested(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    directions: np.ndarray,
    tri: np.ndarray,
    max_gap_px: float,
) -> tuple[np.ndarray, ...]:
    """Every triangle's verdict on its rings, unit normal toward the camera, weight (1 / its longest
    edge: rig.pipeline.normals.vertex_normals), slant to the camera and foreshortening to both
    devices (rig.pipeline.flanks): a compiled pass over spans of the triangles on the pool
    (rig.kernels.triangles.triangle_tests), from the samples' depths and projector pixels."""
    depths = np.ones((len(points), 2))
    for k, device in enumerate((camera, projector)):
        if device.projection != "orthographic":
            depths[:, k] = device.to_device(points)[:, 2]
    focal = (float(camera.K[0, 0]), float(projector.K[0, 0]))
    count = len(tri)
    out = (np.empty(count, np.int8), np.empty((count, 3)), np.empty(count), np.empty(count), np.empty(count))
    arrays = (
        np.ascontiguousarray(tri, np.int64), ring.astype(np.int64), np.ascontiguousarray(xy, np.float64),
        projector.project(points)[0], np.ascontiguousarray(points, np.float64), directions, depths,
        (float(max_gap_px), *focal),
    )  # fmt: skip
    list(pool().map(lambda span: triangle_kernels.triangle_tests(*arrays, *out, *span), batches(count)))
    return out


def _off_its_corners(normals: np.ndarray, tri: np.ndarray, face: np.ndarray, max_excess_deg: float) -> np.ndarray:
    """Triangles `tri` tilted away from a corner's normal (`normals`) by `max_excess_deg` more than
    the corners' normals differ among themselves: the corners agree on a surface the triangle does not
    lie on, as when it joins the rings of two treads of a step. On a smooth surface a triangle's
    normal lies among its corners' normals. A compiled pass on the pool (rig.kernels.normals.off_corners)."""
    tri, off = np.ascontiguousarray(tri, np.int64), np.empty(len(face), np.bool_)
    arrays = (normals, tri, face, max_excess_deg, off)
    list(pool().map(lambda span: normal_kernels.off_corners(*arrays, *span), batches(len(face))))
    return off


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
    if method not in INTERPOLANTS:
        raise ValueError(f"unknown interpolant {method!r}; known: {', '.join(INTERPOLANTS)}")
    settings = settings or SurfaceSettings()  # `tri`: the samples' Delaunay triangles, if known
    triangles = ring_triangles(points, xy, ring, camera, projector, settings, tri)
    counts = triangles.counts
    pixel, owner, kept = rasterize(xy, triangles.tri, camera.width, camera.height, lit, settings.max_unlit)
    if lit is not None:  # triangles over a shadow dropped
        counts["dropped_shadow"] = int(len(kept) - kept.sum())
        counts["faces"] -= counts["dropped_shadow"]
        if not kept.all():
            triangles = triangles.subset(kept)
    tri, normals = triangles.tri, triangles.normals
    grid, ok, agree = _points_in_faces(
        points, xy, triangles, camera, projector, (pixel, owner), method, bands, settings
    )
    # pixels off their bands, and every pixel of a face with many (it bridges an edge); the pixels
    # as images then: the fill's peak of memory holds no per-pixel lists of the faces'
    tested = len(tri) if bands is not None else 0
    valid, triangle, dropped = settled_pixels((pixel, owner), (ok, agree), tested, settings.max_band_disagreement, grid)
    if bands is not None:
        counts["dropped_band_px"] = dropped
    pixels = int(np.count_nonzero(ok))
    del pixel, owner, ok, agree
    if bands is not None and settings.fill:
        filled = _filled(points, normals, xy, ring, tri, camera, projector, valid, lit, bands, grid, settings)
        valid[filled] = True
        counts["filled_px"], pixels = len(filled), pixels + len(filled)
    counts["pixels"] = pixels
    shape = (camera.height, camera.width)
    return RingSurface(
        points, normals, tri, grid.reshape(*shape, 3), valid.reshape(shape), counts, ring, triangle.reshape(shape),
        flank=triangles.flank,
    )  # fmt: skip


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
    """The flat camera grid (H*W, 3) with each pixel's point on its face (pixels: flat pixels and
    their faces, rasterize's) by `method`, NaN elsewhere; per pixel whether a point was found, and
    (with `bands`) whether it lies in the band its pixel read. Batches of pixels on the pool."""
    pixel, owner = pixels
    tri = triangles.tri
    corners = (
        crease_normals(tri, triangles.normals, triangles.face, triangles.weight) if method == "quadratic" else None
    )
    common_origin = camera.center if camera.projection != "orthographic" else None
    terms = FaceTerms.of(points, xy, tri, corners, common_origin)
    grid = full((camera.height * camera.width, 3), np.nan, np.float64)
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
    in_triangle = np.flatnonzero(np.bincount(tri.ravel(), minlength=len(points)) > 0)
    annulus = bands.annulus.ravel()[candidate].astype(np.int64)
    found = disc_points(grid, mask, candidate, annulus, camera)  # an inner disc the rings close around
    rest = ~np.isfinite(found).all(axis=1)
    found[rest] = fill_points(
        points[in_triangle], normals[in_triangle], xy[in_triangle], ring[in_triangle], camera, candidate[rest],
        annulus[rest], settings.fill_settings,
    )  # fmt: skip
    keep = np.isfinite(found).all(axis=1)
    keep[keep] = band_agreement(found[keep], candidate[keep], projector, bands, settings)
    grid[candidate[keep]] = found[keep]
    return candidate[keep]


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
    points = (np.ascontiguousarray(found, np.float64), rows)
    surface_kernels.band_agreement(points, pixel, device, kind, read, margins, agree, 0, len(pixel))
    return agree


def _cubic_depth(points: np.ndarray, xy: np.ndarray, camera: CameraModel, pixel: np.ndarray) -> np.ndarray:
    """Distance along each pixel's ray by Clough-Tocher over the image, from the samples' distances."""
    distance = np.linalg.norm(points - camera.center, axis=1)
    interpolant = CloughTocher2DInterpolator(xy, distance)
    query = np.column_stack([pixel % camera.width, pixel // camera.width]).astype(np.float64)
    return np.asarray(interpolant(query), dtype=np.float64)
