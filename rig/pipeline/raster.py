"""From triangles to pixels: which camera pixels each image triangle covers, and where each pixel's
ray meets its triangle's interpolated surface (rig.pipeline.surface)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.lazy import lazy_module
from rig.workers import batches, full_on_pool, in_row_strips, pool

triangle_kernels = lazy_module("rig.kernels.triangles")  # numba compiles on first use
surface_kernels = lazy_module("rig.kernels.ring_surface")


def rasterize(
    xy: np.ndarray, tri: np.ndarray, width: int, height: int, lit: np.ndarray | None = None, max_unlit: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera pixels (flat indices, in order) whose centres lie in the image triangles, and the
    triangle of each (a pixel on a shared edge goes to the later one); with `lit` (H, W), a triangle
    over more than `max_unlit` of its pixels dark spans a shadow and is dropped. Returns the pixels,
    their triangles renumbered among those kept, and which were kept. Scanline, a compiled loop over
    the triangles for each strip of rows on the pool, then two over the strips
    (rig.kernels.triangles.rasterize, face_areas, kept_pixels)."""
    image = np.empty((height, width), dtype=np.int32)  # a face per pixel: far fewer than 2**31
    xy, tri = np.ascontiguousarray(xy, np.float64), np.ascontiguousarray(tri, np.int64)
    in_row_strips(height, lambda rows: triangle_kernels.rasterize(xy, tri, image, (rows.start, rows.stop)))
    checked = np.zeros((0, 0), np.bool_) if lit is None else np.ascontiguousarray(lit, np.bool_)
    return _listed(image, checked, len(tri), max_unlit)


def _listed(image: np.ndarray, lit: np.ndarray, faces: int, max_unlit: float) -> tuple[np.ndarray, ...]:
    """rasterize's pixels, their faces renumbered and which faces were kept, from the rasterised
    `image`: two passes over strips of rows on the pool, the faces' pixels and dark ones counted,
    then the kept ones listed, each strip from where the strips above it end."""
    strips = batches(image.shape[0])
    area, dark = np.zeros((len(strips), faces), np.int64), np.zeros((len(strips), faces), np.int64)
    list(pool().map(lambda k: triangle_kernels.face_areas(image, lit, area[k], dark[k], strips[k]), range(len(strips))))
    kept = ~(dark.sum(axis=0) > max_unlit * np.maximum(area.sum(axis=0), 1))
    renumber = np.cumsum(kept) - kept  # the kept faces before each
    starts = np.concatenate([[0], np.cumsum(area @ kept)])  # each strip's pixels of kept faces
    listed = (np.empty(starts[-1], np.int32), np.empty(starts[-1], np.int32))  # int32: half the memory
    list(
        pool().map(
            lambda k: triangle_kernels.kept_pixels(image, kept, renumber, listed, int(starts[k]), strips[k]),
            range(len(strips)),
        )
    )
    return listed[0], listed[1], kept


@dataclass(frozen=True, eq=False)
class FaceTerms:
    """Per-face terms every pixel of a face shares, computed once for all batches of pixels (each a
    row over the faces)."""

    plane: np.ndarray  # (3, F) unit normal of the corners' plane
    plane_offset: np.ndarray  # (F,) plane . (corner 0 - origin)
    longest: np.ndarray  # (F,) longest edge, mm
    barycentric: np.ndarray  # (3, 3, F): corner k's weight at pixel (x, y) is [k, 0] x + [k, 1] y + [k, 2]
    origin: np.ndarray | None  # the rays' common origin (a pinhole's centre) the offsets are from; None: per ray
    corner_normals: np.ndarray | None = None  # (3, 3, F) [corner, axis]: the quadratic's tangent planes
    corner_offset: np.ndarray | None = None  # (3, F) each tangent plane's normal . (its corner - origin)

    @staticmethod
    def of(
        points: np.ndarray,
        xy: np.ndarray,
        tri: np.ndarray,
        corner_normals: np.ndarray | None = None,
        origin: np.ndarray | None = None,
    ) -> FaceTerms:
        """The terms of faces `tri`; with `corner_normals` (F, 3, 3; rig.pipeline.normals.crease_normals),
        those of the quadratic interpolant. `origin`: the point every ray starts from, if they share one."""
        count, quadratic = len(tri), corner_normals is not None
        faces = (np.empty((3, count)), np.empty(count), np.empty(count), np.empty((3, 3, count)))
        corners = (np.empty((3, 3, count if quadratic else 0)), np.empty((3, count if quadratic else 0)))
        surface_kernels.face_terms(
            np.ascontiguousarray(points, np.float64), np.ascontiguousarray(xy, np.float64),
            np.ascontiguousarray(tri, np.int64),
            np.ascontiguousarray(corner_normals, np.float64) if quadratic else np.empty((0, 3, 3)),
            np.zeros(3) if origin is None else np.asarray(origin, np.float64), faces, corners,
        )  # fmt: skip
        return FaceTerms(*faces, origin, *(corners if quadratic else (None, None)))


def points_on_faces(
    faces: FaceTerms,
    pixel: np.ndarray,
    owner: np.ndarray,
    rays: tuple[np.ndarray, np.ndarray],
    width: int,
    out: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """Each pixel's point on its triangle (`owner`): on the plane of the corners, or (with the faces'
    corner normals: quadratic) the mean of that and the blend of the corners' tangent planes,
    weighted by the pixel's barycentric coordinates in the image (against the 3D ones they differ by
    the depth's relative change across a triangle, a fraction of a percent of a correction that is
    itself small). A tangent plane the ray meets at a grazing angle leaves the linear point, and
    the mean stays within a quarter of the face's longest edge of it. `rays`: every camera pixel's
    (rig.geometry.CameraModel.pixel_rays). Into out (found, rows, finite): pixel n's point into
    found[rows[n]] (a flat camera grid with rows the pixels saves a copy) and whether it is finite
    into finite[n]. One compiled loop (rig.kernels.ring_surface)."""
    if faces.corner_normals is not None and faces.corner_offset is not None:
        corners = (faces.corner_normals, faces.corner_offset)
    else:
        corners = (np.empty((0, 3, 0)), np.empty((0, 0)))
    origins = np.asarray(rays[0]) if faces.origin is None else np.asarray(faces.origin, np.float64).reshape(1, 3)
    terms = (faces.plane, faces.plane_offset, faces.longest, faces.barycentric)
    surface_kernels.points_on_faces(terms, corners, (origins, rays[1]), pixel, owner, width, out, 0, len(pixel))


def settled_pixels(
    listed: tuple[np.ndarray, np.ndarray],
    found: tuple[np.ndarray, np.ndarray],
    faces: int,
    limit: float,
    grid: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Which listed pixels (flat pixels, their faces) keep their point (found: a point, in its band),
    by rig.kernels.ring_surface.settle a span of pixels per thread (`faces` > 0: the band test, the
    faces' counts first, span by span, summed): the flat valid and triangle images, the grid's
    other points NaN, and how many found points the band test turned away."""
    spans = batches(len(listed[0]))
    counts = np.zeros((2, len(spans), faces), np.int64)
    if faces:
        list(
            pool().map(
                lambda k: surface_kernels.band_counts(listed[1], found[1], (counts[0, k], counts[1, k]), *spans[k]),
                range(len(spans)),
            )
        )
    totals = (counts[0].sum(axis=0), counts[1].sum(axis=0))
    images = (grid, np.zeros(grid.shape[0], bool), full_on_pool((grid.shape[0],), -1, np.int32))
    dropped = pool().map(lambda span: surface_kernels.settle(listed, found, totals, float(limit), images, *span), spans)
    return images[1], images[2], sum(dropped)
