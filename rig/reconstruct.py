"""Correspondence -> points: triangulation of one (projector, camera) pair, and normals."""

from __future__ import annotations

import cv2
import numpy as np

from rig.geometry import CameraModel, ray_plane, ray_ray_midpoint
from rig.patterns import Correspondence
from rig.pointset import PointSet

_DISTORTION_ITERATIONS = 3


def triangulate(camera: CameraModel, projector: CameraModel, corr: Correspondence) -> tuple[np.ndarray, np.ndarray]:
    """World points per camera pixel (H, W, 3), NaN where invalid, and the validity mask.

    Both projector coordinates decoded: ray-ray (closest approach). One: the camera ray meets the
    plane of that projector column (or row); with projector distortion the plane is refined from
    the other coordinate of the current estimate, a few fixed-point steps.
    """
    shape = (camera.height, camera.width)
    valid = corr.valid.ravel().copy()
    idx = np.flatnonzero(valid)
    origins, directions = camera.pixel_rays
    o, d = origins[idx], directions[idx]
    u = corr.u.ravel()[idx].astype(np.float64) if corr.u is not None else None
    v = corr.v.ravel()[idx].astype(np.float64) if corr.v is not None else None
    if u is not None and v is not None:
        po, pd = projector.rays(np.column_stack([u, v]))
        points, _, ok = ray_ray_midpoint(o, d, po, pd)
    elif u is not None or v is not None:
        points, ok = _ray_coordinate_plane(o, d, projector, u, v)
    else:
        raise ValueError("correspondence codes neither projector columns nor rows")
    out = np.full((len(valid), 3), np.nan)
    out[idx[ok]] = points[ok]
    valid[idx[~ok]] = False
    return out.reshape(*shape, 3), valid.reshape(shape)


def _ray_coordinate_plane(o: np.ndarray, d: np.ndarray, projector: CameraModel, u: np.ndarray | None,
                          v: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    coded = u if u is not None else v
    assert coded is not None
    other = np.full(len(coded), projector.K[1, 2] if u is not None else projector.K[0, 2])
    iterations = _DISTORTION_ITERATIONS if projector.has_distortion else 1
    points, ok = o, np.zeros(len(coded), dtype=bool)
    for _ in range(iterations):
        uv = np.column_stack([coded, other]) if u is not None else np.column_stack([other, coded])
        xy = projector.normalized(uv)
        if u is not None:
            normals, offsets = projector.plane_through_column(xy[:, 0])
        else:
            normals, offsets = projector.plane_through_row(xy[:, 1])
        points, ok = ray_plane(o, d, normals, offsets)
        if iterations > 1:
            puv, _ = projector.project(points)
            other = np.where(ok, puv[:, 1] if u is not None else puv[:, 0], other)
    return points, ok


def grid_normals(points: np.ndarray, camera_center: np.ndarray, step: int = 2) -> np.ndarray:
    """Unit normals of an organised point grid (H, W, 3) from neighbours `step` pixels away,
    oriented toward the camera; NaN where a neighbour is missing."""
    p = points
    du = np.full_like(p, np.nan)
    dv = np.full_like(p, np.nan)
    du[:, step:-step] = p[:, 2 * step:] - p[:, : -2 * step]
    dv[step:-step] = p[2 * step:] - p[: -2 * step]
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm
    flip = np.einsum("ijk,ijk->ij", n, camera_center - p) < 0
    n[flip] *= -1
    return n


def fill_missing_normals(normals: np.ndarray, points: np.ndarray, camera_center: np.ndarray) -> np.ndarray:
    """Where a grid normal is missing (edges of valid regions) use the direction to the camera."""
    missing = ~np.isfinite(normals).all(axis=2) & np.isfinite(points).all(axis=2)
    out = normals.copy()
    to_cam = camera_center - points[missing]
    out[missing] = to_cam / np.linalg.norm(to_cam, axis=1, keepdims=True)
    return out


def pair_pointset(camera: CameraModel, projector: CameraModel, corr: Correspondence, source: int) -> tuple[
        PointSet, np.ndarray]:
    """Triangulate one pair into a PointSet (normals, colours from the lit frame) and return it with
    the organised (H, W, 3) point grid."""
    grid, valid = triangulate(camera, projector, corr)
    normals = fill_missing_normals(grid_normals(grid, camera.center), grid, camera.center)
    idx = np.flatnonzero(valid.ravel())
    texture = corr.texture
    if texture.ndim == 2:
        rgb = cv2.cvtColor(_to_uint8(texture), cv2.COLOR_GRAY2RGB)
    else:
        rgb = cv2.cvtColor(_to_uint8(texture), cv2.COLOR_BGR2RGB)
    points = PointSet(
        points=grid.reshape(-1, 3)[idx],
        normals=normals.reshape(-1, 3)[idx].astype(np.float32),
        colors=rgb.reshape(-1, 3)[idx],
        quality=corr.quality.ravel()[idx].astype(np.float32),
        source=np.full(len(idx), source, dtype=np.uint8),
        pixel=idx.astype(np.int64),
    )
    return points, grid


def _to_uint8(image: np.ndarray) -> np.ndarray:
    if image.dtype == np.uint8:
        return image
    return (image.astype(np.float32) * (255.0 / max(1, int(image.max())))).astype(np.uint8)
