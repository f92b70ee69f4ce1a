"""Correspondence -> points: triangulation of one (projector, camera) pair, and normals."""

from __future__ import annotations

import cv2
import numpy as np

from rig.geometry import CameraModel, closest_on_first_ray
from rig.patterns import Correspondence
from rig.pipeline.pointset import PointSet

_DISTORTION_ITERATIONS = 3


class PairTriangulator:
    """Triangulation for one (camera, projector) pair, with per-pixel terms computed once.

    Both projector coordinates decoded: ray-ray (closest approach). One: the camera ray meets the
    plane of that projector column (or row). That plane is affine in the normalized projector
    coordinate x: normal a + x b, offset c0 + x c1, so with the dot products of a and b with every
    camera ray precomputed, a scan costs a few element-wise operations per pixel. With projector
    distortion the plane is refined from the other coordinate of the current estimate, a few
    fixed-point steps.
    """

    def __init__(self, camera: CameraModel, projector: CameraModel) -> None:
        self.camera = camera
        self.projector = projector
        self._terms: dict[str, tuple[np.ndarray, ...]] = {}
        self.derived: dict[str, object] = {}  # terms other paths derive from these (rig.pipeline.organised)

    def plane_terms(self, axis: str) -> tuple[np.ndarray, ...]:
        if axis not in self._terms:
            make = self.projector.plane_through_column if axis == "u" else self.projector.plane_through_row
            n0, c0 = make(np.zeros(1))
            n1, c1 = make(np.ones(1))
            a, b = n0[0], n1[0] - n0[0]
            origins, directions = self.camera.pixel_rays
            self._terms[axis] = (
                directions @ a,
                directions @ b,
                origins @ a,
                origins @ b,
                np.float64(c0[0]),
                np.float64(c1[0] - c0[0]),
            )
        return self._terms[axis]

    def planes_affine(self, axis: str) -> bool:
        """Whether the plane of a projector column (or row) is affine in its normalised coordinate
        (the `plane_terms` hold): no projector distortion, no skew across the columns."""
        return not self.projector.has_distortion and (axis == "v" or self.projector.K[0, 1] == 0)

    def triangulate(self, corr: Correspondence) -> tuple[np.ndarray, np.ndarray]:
        """World points per camera pixel (H, W, 3), NaN where invalid, and the validity mask."""
        camera = self.camera
        shape = (camera.height, camera.width)
        if corr.u is None and corr.v is None:
            raise ValueError("correspondence codes neither projector columns nor rows")
        if corr.u is not None and corr.v is not None:
            return self._ray_ray(corr, shape)
        axis = "u" if corr.u is not None else "v"
        coded = corr.u if corr.u is not None else corr.v
        assert coded is not None
        if not self.planes_affine(axis):
            return self._ray_plane_iterative(corr, axis, coded, shape)
        # Fast path: whole-grid arithmetic, invalid pixels are NaN throughout.
        x = self._normalized_linear(np.where(corr.valid, coded, np.nan).ravel().astype(np.float64), axis)
        nd_a, nd_b, no_a, no_b, c0, c1 = self.plane_terms(axis)
        denom = nd_a + x * nd_b
        ok = np.abs(denom) >= 1e-3 * np.sqrt(1 + x * x)
        s = (c0 + x * c1 - no_a - x * no_b) / denom
        ok &= s > 0
        s[~ok] = np.nan
        origins, directions = camera.pixel_rays
        points = origins + s[:, None] * directions
        return points.reshape(*shape, 3), ok.reshape(shape)

    def _ray_ray(self, corr: Correspondence, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Both coordinates decoded: the point of the camera ray closest to the projector ray."""
        assert corr.u is not None and corr.v is not None
        projector = self.projector
        if projector.projection == "pinhole" and not projector.has_distortion and self.camera.projection == "pinhole":
            return self._ray_ray_fast(corr, shape)
        idx = np.flatnonzero(corr.valid.ravel())
        uv = np.column_stack([corr.u.ravel()[idx], corr.v.ravel()[idx]]).astype(np.float64)
        po, pd = projector.rays(uv)
        origins, directions = self.camera.pixel_rays
        points, ok = closest_on_first_ray(origins[idx], directions[idx], po, pd)
        return self._scatter(idx, points, ok, shape)

    def _ray_ray_fast(self, corr: Correspondence, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Whole-grid closest approach for pinhole devices without projector distortion. The
        projector ray of (u, v) is A (u, v, 1) with A = R_p^T K_p^-1, so every dot product the
        solution needs is affine or quadratic in (u, v) with per-pixel coefficients computed once."""
        if "ray_ray" not in self._terms:
            A = self.projector.R.T @ np.linalg.inv(self.projector.K)
            _, directions = self.camera.pixel_rays
            w = self.camera.center - self.projector.center
            self._terms["ray_ray"] = (directions @ A, directions @ w, A.T @ A, A.T @ w)
        d1_a, d1_w, gram, a_w = self._terms["ray_ray"]
        assert corr.u is not None and corr.v is not None
        u = np.where(corr.valid, corr.u, np.nan).ravel().astype(np.float64)
        v = corr.v.ravel().astype(np.float64)
        b = u * d1_a[:, 0] + v * d1_a[:, 1] + d1_a[:, 2]  # d1 . d2
        c = gram[0, 0] * u * u + gram[1, 1] * v * v + 2 * (gram[0, 1] * u * v + gram[0, 2] * u + gram[1, 2] * v)
        c += gram[2, 2]  # |d2|^2
        e = a_w[0] * u + a_w[1] * v + a_w[2]  # d2 . w
        denom = c - b * b
        with np.errstate(invalid="ignore", divide="ignore"):
            ok = denom >= 1e-6 * c
            s1 = (b * e - c * d1_w) / denom
            s2 = (e - b * d1_w) / denom
            ok &= (s1 > 0) & (s2 > 0)
        s1[~ok] = np.nan
        origins, directions = self.camera.pixel_rays
        points = origins + s1[:, None] * directions
        return points.reshape(*shape, 3), ok.reshape(shape)

    def _ray_plane_iterative(
        self, corr: Correspondence, axis: str, coded_grid: np.ndarray, shape: tuple[int, int]
    ) -> tuple[np.ndarray, np.ndarray]:
        projector = self.projector
        idx = np.flatnonzero(corr.valid.ravel())
        coded = coded_grid.ravel()[idx].astype(np.float64)
        nd_a, nd_b, no_a, no_b, c0, c1 = (t[idx] if np.ndim(t) else t for t in self.plane_terms(axis))
        origins, directions = self.camera.pixel_rays
        o, d = origins[idx], directions[idx]
        other = np.full(len(coded), projector.K[1, 2] if axis == "u" else projector.K[0, 2])
        points, ok = o, np.zeros(len(coded), dtype=bool)
        for _ in range(_DISTORTION_ITERATIONS):
            uv = np.column_stack([coded, other] if axis == "u" else [other, coded])
            x = projector.normalized(uv)[:, 0 if axis == "u" else 1]
            denom = nd_a + x * nd_b
            ok = np.abs(denom) >= 1e-3 * np.sqrt(1 + x * x)
            s = (c0 + x * c1 - no_a - x * no_b) / np.where(ok, denom, 1.0)
            ok &= s > 0
            points = o + s[:, None] * d
            puv, _ = projector.project(points)
            other = np.where(ok, puv[:, 1] if axis == "u" else puv[:, 0], other)
        return self._scatter(idx, points, ok, shape)

    @staticmethod
    def _scatter(
        idx: np.ndarray, points: np.ndarray, ok: np.ndarray, shape: tuple[int, int]
    ) -> tuple[np.ndarray, np.ndarray]:
        out = np.full((shape[0] * shape[1], 3), np.nan)
        out[idx[ok]] = points[ok]
        valid = np.zeros(shape[0] * shape[1], dtype=bool)
        valid[idx[ok]] = True
        return out.reshape(*shape, 3), valid.reshape(shape)

    def _normalized_linear(self, coded: np.ndarray, axis: str) -> np.ndarray:
        K = self.projector.K
        if axis == "u":
            return (coded - K[0, 2]) / K[0, 0]
        return (coded - K[1, 2]) / K[1, 1]


def grid_normals(points: np.ndarray, toward: np.ndarray, step: int = 2) -> np.ndarray:
    """Unit normals (float32) of an organised point grid (H, W, 3) from neighbours `step` pixels
    away, oriented against `toward` (H, W, 3: the camera ray directions). Where a neighbour is
    missing the normal faces the camera (-toward)."""
    p = points.astype(np.float32)
    h, w = p.shape[:2]
    n = np.full_like(p, np.nan)
    core = (slice(step, h - step), slice(step, w - step))
    du = p[step:-step, 2 * step :] - p[step:-step, : -2 * step]
    dv = p[2 * step :, step:-step] - p[: -2 * step, step:-step]
    n[core] = np.cross(du, dv)
    norm = np.sqrt(np.einsum("ijk,ijk->ij", n, n))
    facing = np.einsum("ijk,ijk->ij", n, toward)
    n *= (np.where(facing > 0, -1.0, 1.0).astype(np.float32) / norm)[..., None]
    return np.where(np.isfinite(norm)[..., None], n, -toward)


def pair_pointset(
    grid: np.ndarray, valid: np.ndarray, camera: CameraModel, corr: Correspondence, source: int
) -> PointSet:
    """The PointSet of one pair's organised points (normals, colours from the lit frame)."""
    directions = camera.pixel_rays[1].reshape(camera.height, camera.width, 3).astype(np.float32)
    normals = grid_normals(grid, directions)
    idx = np.flatnonzero(valid.ravel())
    rgb = texture_rgb(corr)
    points = PointSet(
        points=grid.reshape(-1, 3)[idx],
        normals=normals.reshape(-1, 3)[idx],
        colors=rgb.reshape(-1, 3)[idx],
        quality=corr.quality.ravel()[idx].astype(np.float32),
        source=np.full(len(idx), source, dtype=np.uint8),
        pixel=idx.astype(np.int64),
    )
    return points


def texture_rgb(corr: Correspondence) -> np.ndarray:
    """The lit frame as 8-bit RGB (H, W, 3)."""
    image = _to_uint8(corr.texture, corr.full_scale)
    return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB if image.ndim == 2 else cv2.COLOR_BGR2RGB)


def _to_uint8(image: np.ndarray, full_scale: int) -> np.ndarray:
    if image.dtype == np.uint8 and full_scale == 255:
        return image
    return np.clip(image.astype(np.float32) * (255.0 / full_scale), 0, 255).astype(np.uint8)


def reject_isolated(
    grid: np.ndarray, valid: np.ndarray, camera: CameraModel, max_jump_mm: float, min_support: int = 3
) -> np.ndarray:
    """Mask of points to keep: those with at least `min_support` of their 8 neighbours within
    `max_jump_mm` in depth.

    A mixed pixel on a depth edge decodes to neither surface; it can agree with the mixed pixels
    above and below it along the edge (two neighbours) but not with a third, while a point of a
    surface, even on its border or at a corner, has three. Isolated decoding errors go too. A smooth
    surface keeps its points unless it is so steep that neighbouring pixels differ by more than the
    limit (grazing views, whose points are the least accurate anyway).
    """
    depth = (grid @ camera.axis - camera.center @ camera.axis).astype(np.float32)  # NaN where invalid
    support = np.zeros(valid.shape, dtype=np.uint8)
    h, w = valid.shape
    with np.errstate(invalid="ignore"):
        # Each neighbour pair is compared once and counts for both of its pixels.
        for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
            rows_p, rows_q = slice(0, h - dy), slice(dy, h)
            cols_p = slice(0, w - dx) if dx >= 0 else slice(-dx, w)
            cols_q = slice(dx, w) if dx >= 0 else slice(0, w + dx)
            close = np.abs(depth[rows_p, cols_p] - depth[rows_q, cols_q]) <= max_jump_mm
            support[rows_p, cols_p] += close
            support[rows_q, cols_q] += close
    return valid & (support >= min_support)
