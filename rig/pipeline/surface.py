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

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from scipy.interpolate import CloughTocher2DInterpolator

from rig.geometry import CameraModel
from rig.pipeline.normals import crease_normals, face_normals, face_weights, smoothed_normals, vertex_normals
from rig.pipeline.raster import FaceTerms, on_triangles, rasterize
from rig.pipeline.workers import batches, pool

Interpolant = Literal["linear", "quadratic", "cubic"]
INTERPOLANTS: tuple[str, ...] = ("linear", "quadratic", "cubic")

# Near the rings' centre the polar angle says little (and is read poorly): no angle check inside this.
_ANGLE_MIN_RADIUS_PX = 8.0


@dataclass(frozen=True)
class SurfaceSettings:
    max_gap_px: float = 6.0  # two samples of one ring further apart than this are not neighbours
    max_slant_deg: float = 84.0  # triangles seen more edge-on than this span a depth edge
    max_bend_deg: float = 50.0  # ... as do triangles this far from one of their corners' normals
    min_foreshortening: float = 0.15  # ... and edges steep to both devices (see _bridges)
    max_unlit: float = 0.2  # triangles over more of their pixels dark than this span a shadow
    band_margin_px: float = 2.0  # a point may project this far outside the annulus its pixel read ...
    band_angle_rad: float = 0.15  # ... and this far from the polar angle it read (3x the code's p99.9)
    normal_smoothing_px: float = 4.0  # samples' normals averaged over their ring this far either way
    max_band_disagreement: float = 0.25  # a triangle with more of its pixels off their bands bridges an edge


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


def ring_triangles(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    settings: SurfaceSettings,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """Kept triangles (F, 3) of the samples' image Delaunay triangulation, their unit normals and
    the samples' (both facing the camera), and how many triangles each test dropped."""
    _, rays = camera.rays(xy)
    directions = np.asarray(rays)
    tri = delaunay(xy)
    counts = {"triangles": len(tri)}
    r = ring[tri]
    span = r.max(axis=1) - r.min(axis=1)
    same = r == np.roll(r, -1, axis=1)  # edge k joins corner k and k+1 on one ring
    edge_px = np.linalg.norm(xy[tri] - np.roll(xy[tri], -1, axis=1), axis=2)
    gap = (same & (edge_px > settings.max_gap_px)).any(axis=1)
    keep = (span == 1) & ~gap
    counts["dropped_ring_skipped"] = int((span > 1).sum())
    counts["dropped_gap"] = int(((span == 1) & gap).sum())
    counts["dropped_one_ring"] = int((span == 0).sum())
    tri = tri[keep]
    face = face_normals(points, tri, directions)
    slant = np.abs(np.einsum("ij,ij->i", face, directions[tri[:, 0]]))
    edge_on = slant < np.cos(np.radians(settings.max_slant_deg))
    edge_on |= _bridges(points, xy, tri, camera, projector, settings.min_foreshortening)
    tri, face = tri[~edge_on], face[~edge_on]
    normals = vertex_normals(points, tri, face, directions)
    bent = (np.einsum("ikj,ij->ik", normals[tri], face) < np.cos(np.radians(settings.max_bend_deg))).any(axis=1)
    tri, face = tri[~bent], face[~bent]
    counts["dropped_depth_edge"] = int(edge_on.sum() + bent.sum())
    counts["faces"] = len(tri)
    normals = vertex_normals(points, tri, face, directions)
    in_triangle = np.bincount(tri.ravel(), minlength=len(points)) > 0  # the others' normals are a guess
    normals = smoothed_normals(normals, points, xy, ring, in_triangle, settings.normal_smoothing_px)
    return tri, face, normals, counts


def delaunay(xy: np.ndarray) -> np.ndarray:
    """Delaunay triangles (F, 3) of image points, by OpenCV's Subdiv2D (a third of Qhull's time
    here); points that coincide in float32 are triangulated once."""
    if len(xy) < 3:
        return np.zeros((0, 3), np.int64)
    lo, hi = xy.min(axis=0) - 2.0, xy.max(axis=0) + 2.0
    subdiv = cv2.Subdiv2D((int(lo[0]), int(lo[1]), int(hi[0] - lo[0]) + 2, int(hi[1] - lo[1]) + 2))
    coords = np.ascontiguousarray(xy, dtype=np.float32)
    subdiv.insert(coords)
    corners = subdiv.getTriangleList().astype(np.float32).reshape(-1, 3, 2)
    keys = coords.view(np.int64).ravel()  # both float32 coordinates as one exact key
    order = np.argsort(keys)
    found = np.searchsorted(keys[order], np.ascontiguousarray(corners).view(np.int64).reshape(-1, 3))
    found = np.minimum(found, len(keys) - 1)
    index = order[found]
    real = (keys[index] == np.ascontiguousarray(corners).view(np.int64).reshape(-1, 3)).all(axis=1)
    return index[real]  # triangles touching Subdiv2D's outer virtual vertices are dropped


def _bridges(
    points: np.ndarray, xy: np.ndarray, tri: np.ndarray, camera: CameraModel, projector: CameraModel, min_product: float
) -> np.ndarray:
    """Triangles with an edge that both devices see foreshortened: f = (image length x mm per
    pixel at its depth) / 3D length is the cosine of the edge's tilt out of a device's image plane.
    A surface can be steep to one device, rarely to both; an edge joining a surface to another that
    one device hides or shadows runs along a ray of one and steeply for the other."""
    p = points[tri]
    length = np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)
    product = np.ones_like(length)
    for device, image in ((camera, xy[tri]), (projector, None)):
        if image is None:
            image = device.project(p.reshape(-1, 3))[0].reshape(p.shape[0], 3, 2)
        pixels = np.linalg.norm(np.roll(image, -1, axis=1) - image, axis=2)
        product *= np.minimum(1.0, pixels * _mm_per_px(device, p) / np.maximum(length, 1e-12))
    return (product < min_product).any(axis=1)


def _mm_per_px(device: CameraModel, p: np.ndarray) -> np.ndarray:
    """Millimetres per pixel across a device's rays at each corner's depth (F, 3)."""
    if device.projection == "orthographic":
        return np.full(p.shape[:2], 1.0 / device.K[0, 0])
    depth = device.to_device(p.reshape(-1, 3))[:, 2].reshape(p.shape[:2])
    return 0.5 * (depth + np.roll(depth, -1, axis=1)) / device.K[0, 0]


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
) -> RingSurface:
    """The dense surface of one pair's kept ring samples (points, sub-pixel camera positions, ring
    index) by `method` (see the module docstring). `lit` (H, W) marks the pixels the projector
    lights: a triangle over dark pixels spans a shadow (or no surface at all). With `bands`, a pixel
    whose interpolated point the projector would light outside the annulus or away from the angle
    that pixel read is a hole: the triangle there bridges a depth edge its corners cannot see."""
    if method not in INTERPOLANTS:
        raise ValueError(f"unknown interpolant {method!r}; known: {', '.join(INTERPOLANTS)}")
    settings = settings or SurfaceSettings()
    tri, face, normals, counts = ring_triangles(points, xy, ring, camera, projector, settings)
    pixel, owner = rasterize(xy, tri, camera.width, camera.height)
    if lit is not None:
        kept, pixel, owner = _without_shadowed(tri, pixel, owner, lit, settings.max_unlit, counts)
        tri, face = tri[kept], face[kept]
    all_origins, all_directions = camera.pixel_rays
    corners = crease_normals(tri, normals, face, face_weights(points, tri)) if method == "quadratic" else None
    terms = FaceTerms.of(points, xy, tri, corners)

    def solve(span: tuple[int, int]) -> tuple[np.ndarray, np.ndarray | None]:
        part, part_owner = pixel[span[0] : span[1]], owner[span[0] : span[1]]
        rays = (np.asarray(all_origins[part]), np.asarray(all_directions[part]))
        if method == "cubic":
            found = rays[0] + _cubic_depth(points, xy, camera, part)[:, None] * rays[1]
        else:
            found = on_triangles(terms, part, part_owner, rays, camera.width)
        return found, None if bands is None else band_agreement(found, part, projector, bands, settings)

    # cubic: one interpolant over the whole image, not one per batch
    solved = list(pool().map(solve, [(0, len(pixel))] if method == "cubic" else batches(len(pixel))))
    found = np.concatenate([f for f, _ in solved]) if solved else np.zeros((0, 3))
    ok = np.isfinite(found).all(axis=1)
    if bands is not None:
        agree = np.concatenate([a for _, a in solved if a is not None]) if solved else np.zeros(0, bool)
        area = np.bincount(owner, minlength=len(tri))
        bridging = np.bincount(owner, ~agree, minlength=len(tri)) > settings.max_band_disagreement * area
        agree &= ~bridging[owner]
        counts["dropped_band_px"] = int((ok & ~agree).sum())
        ok &= agree
    grid = np.full((camera.height * camera.width, 3), np.nan)
    grid[pixel[ok]] = found[ok]
    valid = np.zeros(camera.height * camera.width, dtype=bool)
    valid[pixel[ok]] = True
    counts["pixels"] = int(ok.sum())
    shape = (camera.height, camera.width)
    triangle = np.full(camera.height * camera.width, -1, dtype=np.int32)
    triangle[pixel[ok]] = owner[ok]
    return RingSurface(
        points, normals, tri, grid.reshape(*shape, 3), valid.reshape(shape), counts, ring, triangle.reshape(shape)
    )


def _without_shadowed(
    tri: np.ndarray, pixel: np.ndarray, owner: np.ndarray, lit: np.ndarray, max_unlit: float, counts: dict[str, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which triangles have at most `max_unlit` of their pixels dark, and their pixels (renumbered)."""
    area = np.bincount(owner, minlength=len(tri))
    dark = np.bincount(owner, ~lit.ravel()[pixel], minlength=len(tri))
    shadowed = dark > max_unlit * np.maximum(area, 1)
    counts["dropped_shadow"] = int(shadowed.sum())
    counts["faces"] -= counts["dropped_shadow"]
    keep = ~shadowed[owner]
    renumber = np.cumsum(~shadowed) - 1
    return ~shadowed, pixel[keep], renumber[owner[keep]]


def band_agreement(
    found: np.ndarray, pixel: np.ndarray, projector: CameraModel, bands: RingBands, settings: SurfaceSettings
) -> np.ndarray:
    """Whether each interpolated point (at flat camera pixel `pixel`) projects into the annulus and
    near the polar angle its pixel read; unread pixels agree with anything."""
    uv, z = projector.project(np.where(np.isfinite(found), found, 0.0))
    du, dv = uv[:, 0] - bands.center_px[0], uv[:, 1] - bands.center_px[1]
    rho = np.hypot(du, dv)
    annulus = bands.annulus.ravel()[pixel].astype(np.int64)
    radii = np.concatenate([[-np.inf], bands.radii_px, [np.inf]])  # annulus a lies between radii[a], radii[a + 1]
    read = annulus >= 0
    a = np.clip(annulus, 0, len(bands.radii_px))
    inside = (rho >= radii[a] - settings.band_margin_px) & (rho <= radii[a + 1] + settings.band_margin_px)
    angle = bands.angle.ravel()[pixel]
    turned = np.abs(np.remainder(np.arctan2(dv, du) - angle + np.pi, 2 * np.pi) - np.pi)
    aligned = ~np.isfinite(angle) | (turned <= settings.band_angle_rad) | (rho < _ANGLE_MIN_RADIUS_PX)
    return (z > 0) & (~read | inside) & aligned


def _cubic_depth(points: np.ndarray, xy: np.ndarray, camera: CameraModel, pixel: np.ndarray) -> np.ndarray:
    """Distance along each pixel's ray by Clough-Tocher over the image, from the samples' distances."""
    distance = np.linalg.norm(points - camera.center, axis=1)
    interpolant = CloughTocher2DInterpolator(xy, distance)
    query = np.column_stack([pixel % camera.width, pixel // camera.width]).astype(np.float64)
    return np.asarray(interpolant(query), dtype=np.float64)
