"""From triangles to pixels: which camera pixels each image triangle covers, and where each pixel's
ray meets its triangle's interpolated surface (rig.pipeline.surface)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.pipeline.workers import batches, pool


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
    """Flat pixel indices covered by faces [first_face, end_face) and their face numbers."""
    corners = xy[tri[first_face:end_face]]  # (F, 3, 2)
    top = np.clip(np.ceil(corners[:, :, 1].min(axis=1)), 0, height - 1).astype(np.int64)
    bottom = np.clip(np.floor(corners[:, :, 1].max(axis=1)), 0, height - 1).astype(np.int64)
    rows_per = np.maximum(bottom - top + 1, 0)
    owner = np.repeat(np.arange(len(corners)), rows_per)
    row = top[owner] + np.arange(len(owner)) - np.repeat(np.cumsum(rows_per) - rows_per, rows_per)
    left = np.full(len(owner), np.inf)
    right = np.full(len(owner), -np.inf)
    for k in range(3):  # per edge, per face: its y range and x at y = 0, then per row one multiply-add
        a, b = corners[:, k], corners[:, (k + 1) % 3]
        dy = b[:, 1] - a[:, 1]
        slope = np.divide(b[:, 0] - a[:, 0], dy, out=np.zeros_like(dy), where=dy != 0)
        low = np.where(dy != 0, np.minimum(a[:, 1], b[:, 1]), np.inf)[owner]  # a flat edge crosses no row
        high = np.maximum(a[:, 1], b[:, 1])[owner]
        x = (a[:, 0] - a[:, 1] * slope)[owner] + row * slope[owner]
        crosses = (low <= row) & (row <= high)
        left = np.where(crosses, np.minimum(left, x), left)
        right = np.where(crosses, np.maximum(right, x), right)
    first = np.clip(np.ceil(left), 0, width).astype(np.int64, copy=False) if len(left) else left.astype(np.int64)
    last = np.clip(np.floor(right), -1, width - 1).astype(np.int64, copy=False) if len(right) else first
    count = np.maximum(last - first + 1, 0)
    column = np.repeat(first, count) + np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return np.repeat(row, count) * width + column, np.repeat(owner, count) + first_face


@dataclass(frozen=True, eq=False)
class FaceTerms:
    """Per-face terms every pixel of a face shares, computed once for all batches of pixels."""

    plane: np.ndarray  # (F, 3) normal (unnormalised) of the corners' plane
    plane_offset: np.ndarray  # (F,) plane . corner 0
    longest: np.ndarray  # (F,) longest edge, mm
    image_origin: np.ndarray  # (F, 2) corner 0 in the image
    image_inverse: np.ndarray  # (F, 2, 2): image offset from corner 0 -> barycentric (b1, b2)
    corner_normals: np.ndarray | None = None  # (F, 3, 3) the quadratic's tangent planes (None: linear)
    corner_offset: np.ndarray | None = None  # (F, 3) each tangent plane's normal . its corner

    @staticmethod
    def of(points: np.ndarray, xy: np.ndarray, tri: np.ndarray, corner_normals: np.ndarray | None = None) -> FaceTerms:
        """The terms of faces `tri`; with `corner_normals` (rig.pipeline.normals.crease_normals),
        those of the quadratic interpolant."""
        corner = points[tri]
        plane = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
        longest = np.linalg.norm(corner - np.roll(corner, -1, axis=1), axis=2).max(axis=1)
        image = xy[tri]
        e1, e2 = image[:, 1] - image[:, 0], image[:, 2] - image[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        inverse = np.stack([np.column_stack([e2[:, 1], -e2[:, 0]]), np.column_stack([-e1[:, 1], e1[:, 0]])], axis=1)
        offset = np.einsum("ij,ij->i", plane, corner[:, 0])
        corner_offset = None if corner_normals is None else np.einsum("fkj,fkj->fk", corner_normals, corner)
        return FaceTerms(
            plane, offset, longest, image[:, 0], inverse / det[:, None, None], corner_normals, corner_offset
        )


def on_triangles(
    faces: FaceTerms, pixel: np.ndarray, owner: np.ndarray, rays: tuple[np.ndarray, np.ndarray], width: int
) -> np.ndarray:
    """Each pixel's point on its triangle (`owner`): on the plane of the corners, or (with the faces'
    corner normals: quadratic) the mean of that and the blend of the corners' tangent planes,
    weighted by the pixel's barycentric coordinates in the image (against the 3D ones they differ by
    the depth's relative change across a triangle, a fraction of a percent of a correction that is
    itself small)."""
    origins, directions = rays
    t_linear = ray_plane(origins, directions, faces.plane[owner], faces.plane_offset[owner])
    if faces.corner_normals is None or faces.corner_offset is None:
        return origins + t_linear[:, None] * directions
    offset = np.column_stack([pixel % width, pixel // width]) - faces.image_origin[owner]
    b = np.einsum("pij,pj->pi", faces.image_inverse[owner], offset)
    weights = np.column_stack([1.0 - b[:, 0] - b[:, 1], b])
    normals = faces.corner_normals[owner]  # (P, 3, 3)
    facing = np.einsum("pkj,pj->pk", normals, directions)
    toward = faces.corner_offset[owner] - np.einsum("pkj,pj->pk", normals, origins)
    steep = (np.abs(facing) < 0.1).any(axis=1)  # a tangent plane met at a grazing angle
    with np.errstate(divide="ignore", invalid="ignore"):
        blend = np.einsum("pk,pk->p", weights, toward / facing)
    longest = faces.longest[owner]
    t = np.where(steep, t_linear, 0.5 * (t_linear + blend))
    t = np.clip(t, t_linear - 0.25 * longest, t_linear + 0.25 * longest)
    return origins + t[:, None] * directions


def ray_plane(origins: np.ndarray, rays: np.ndarray, normal: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Distance along each ray to the plane normal . x = offset."""
    denominator = np.einsum("ij,ij->i", rays, normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (offset - np.einsum("ij,ij->i", origins, normal)) / denominator
