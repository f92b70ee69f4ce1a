"""From triangles to pixels: which camera pixels each image triangle covers, and where each pixel's
ray meets its triangle's interpolated surface (rig.pipeline.surface)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.workers import batches, pool


def rasterize(xy: np.ndarray, tri: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Camera pixels (flat indices) whose centres lie in the image triangles, and the triangle of
    each (a pixel on a shared edge goes to one of them). Scanline: each triangle's rows, each row's
    span between the edges it crosses; batches of triangles on the pool's threads."""
    parts = list(pool().map(lambda ab: _spans(xy, tri, ab[0], ab[1], width, height), batches(len(tri), 1)))
    image = np.full(width * height, -1, dtype=np.int64)
    for flat, owner in parts:
        image[flat] = owner  # a pixel on a shared edge: one wins
    pixel = np.flatnonzero(image >= 0)
    return pixel, image[pixel]


def _spans(
    xy: np.ndarray, tri: np.ndarray, first_face: int, end_face: int, width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """Flat pixel indices covered by faces [first_face, end_face) and their face numbers. With its
    corners sorted by y, a triangle's rows run between its long edge (top to bottom) and, above the
    middle corner, the upper short edge, below it the lower one."""
    corners = xy[tri[first_face:end_face]]  # (F, 3, 2)
    order = np.argsort(corners[:, :, 1], axis=1, kind="stable")
    (x0, x1, x2), (y0, y1, y2) = np.take_along_axis(corners, order[:, :, None], axis=1).transpose(2, 1, 0)
    top = np.clip(np.ceil(y0), 0, height - 1).astype(np.int64)
    bottom = np.clip(np.floor(y2), 0, height - 1).astype(np.int64)
    rows_per = np.where(y2 > y0, np.maximum(bottom - top + 1, 0), 0)  # a flat triangle has no inside
    owner = np.repeat(np.arange(len(corners)), rows_per)
    row = top[owner] + np.arange(len(owner)) - np.repeat(np.cumsum(rows_per) - rows_per, rows_per)
    long_at, long_slope = _edge(x0, y0, x2, y2)
    (upper_at, upper_slope), (lower_at, lower_slope) = _edge(x0, y0, x1, y1), _edge(x1, y1, x2, y2)
    short_at, short_slope = np.column_stack([upper_at, lower_at]), np.column_stack([upper_slope, lower_slope])
    short = 2 * owner + (row > y1[owner])  # flat index of the short edge of each row
    x_long = long_at[owner] + row * long_slope[owner]
    x_short = short_at.ravel()[short] + row * short_slope.ravel()[short]
    left, right = np.minimum(x_long, x_short), np.maximum(x_long, x_short)
    first = np.clip(np.ceil(left), 0, width).astype(np.int64, copy=False) if len(left) else left.astype(np.int64)
    last = np.clip(np.floor(right), -1, width - 1).astype(np.int64, copy=False) if len(right) else first
    count = np.maximum(last - first + 1, 0)
    # each span's pixels: its first flat index, then consecutive (one repeat and one arange in all)
    start = row * width + first - (np.cumsum(count) - count)
    return np.repeat(start, count) + np.arange(count.sum()), np.repeat(owner + first_face, count)


@dataclass(frozen=True, eq=False)
class FaceTerms:
    """Per-face terms every pixel of a face shares, computed once for all batches of pixels. Each
    term is a row over the faces: a pixel batch gathers it by its faces from a small array that
    stays in cache, and computes on contiguous rows (a third of the time of gathering (F, 3) rows)."""

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
        corner = points[tri] - (0.0 if origin is None else origin)
        plane = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
        plane /= np.maximum(np.linalg.norm(plane, axis=1), 1e-300)[:, None]
        longest = np.linalg.norm(corner - corner[:, [1, 2, 0]], axis=2).max(axis=1)
        image = xy[tri]
        e1, e2 = image[:, 1] - image[:, 0], image[:, 2] - image[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        # (b1, b2) = inverse @ (pixel - corner 0), as affine functions of the pixel
        b1 = np.stack([e2[:, 1], -e2[:, 0]]) / det
        b2 = np.stack([-e1[:, 1], e1[:, 0]]) / det
        c1, c2 = -(b1 * image[:, 0].T).sum(axis=0), -(b2 * image[:, 0].T).sum(axis=0)
        weights = np.stack(
            [np.vstack([-b1[0] - b2[0], -b1[1] - b2[1], 1.0 - c1 - c2]), np.vstack([*b1, c1]), np.vstack([*b2, c2])]
        )
        offset = np.einsum("ij,ij->i", plane, corner[:, 0])
        normals = None if corner_normals is None else np.ascontiguousarray(corner_normals.transpose(1, 2, 0))
        corner_offset = None if corner_normals is None else np.einsum("fkj,fkj->kf", corner_normals, corner)
        return FaceTerms(np.ascontiguousarray(plane.T), offset, longest, weights, origin, normals, corner_offset)


def on_triangles(
    faces: FaceTerms, pixel: np.ndarray, owner: np.ndarray, rays: tuple[np.ndarray, np.ndarray], width: int
) -> np.ndarray:
    """Each pixel's point on its triangle (`owner`): on the plane of the corners, or (with the faces'
    corner normals: quadratic) the mean of that and the blend of the corners' tangent planes,
    weighted by the pixel's barycentric coordinates in the image (against the 3D ones they differ by
    the depth's relative change across a triangle, a fraction of a percent of a correction that is
    itself small)."""
    origins, directions = rays
    d = [np.ascontiguousarray(directions[:, j]) for j in range(3)]

    def along(normal: np.ndarray, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ray parameter where each pixel's ray meets its face's plane (rows gathered by owner),
        and the cosine of the ray with that plane's normal."""
        n = [row[owner] for row in normal]
        facing = n[0] * d[0] + n[1] * d[1] + n[2] * d[2]
        numerator = offset[owner]
        if faces.origin is None:
            numerator = numerator - np.einsum("ij,ij->i", origins, np.column_stack(n))
        with np.errstate(divide="ignore", invalid="ignore"):
            return numerator / facing, facing

    t_linear, _ = along(faces.plane, faces.plane_offset)
    t = t_linear
    if faces.corner_normals is not None and faces.corner_offset is not None:
        x, y = (pixel % width).astype(np.float64), (pixel // width).astype(np.float64)
        blend = np.zeros(len(pixel))
        steep = np.zeros(len(pixel), dtype=bool)
        for k in range(3):
            t_k, facing = along(faces.corner_normals[k], faces.corner_offset[k])
            steep |= np.abs(facing) < 0.1  # a tangent plane met at a grazing angle
            w = faces.barycentric[k]
            blend += (w[0][owner] * x + w[1][owner] * y + w[2][owner]) * t_k
        reach = 0.25 * faces.longest[owner]
        t = np.where(steep, t_linear, 0.5 * (t_linear + blend))
        t = np.clip(t, t_linear - reach, t_linear + reach)
    start = faces.origin if faces.origin is not None else origins
    return start + t[:, None] * directions


def _edge(xa: np.ndarray, ya: np.ndarray, xb: np.ndarray, yb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An edge from (xa, ya) down to (xb, yb) as x = at + y * slope; a flat edge as x = xb (it is
    met only in its own row, where the other edges give its other end)."""
    dy = yb - ya
    slope = np.divide(xb - xa, dy, out=np.zeros_like(dy), where=dy != 0)
    return np.where(dy != 0, xa - ya * slope, xb), slope
