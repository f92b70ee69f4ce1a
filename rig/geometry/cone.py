"""Camera rays against the cone of a projector ring (a cylinder for an orthographic projector).

A ring of radius R about (u0, v0) in the projector image is the conic
    (x0 - u0 x2)^2 + (x1 - v0 x2)^2 - R^2 x2^2 = 0
of the projector's homogeneous image point x. Along a camera ray X = o + s d, x is affine in s
(pinhole: x = K (R_p X + t_p); orthographic: x = (fx X + cx, fy Y + cy, 1) in the device frame), so
the ray meets the ring in the roots of a quadratic in s: usually two, in front of the projector.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.geometry.camera import CameraModel
from rig.lazy import lazy_module
from rig.workers import batches, pool

_cone = lazy_module("rig.kernels.cone")


@dataclass(frozen=True, eq=False)
class ConeHits:
    """Both intersections of each ray with its ring's cone; arrays (M, 2[, 3])."""

    s: np.ndarray  # ray parameters, NaN where there is no valid root
    points: np.ndarray  # world points
    theta: np.ndarray  # projector polar angle of each root about the ring centre
    ds_dradius: np.ndarray  # change of s per pixel of ring radius (conditioning)
    cos_beta: np.ndarray  # |cos| of the angle between the ring's radial direction and the epipolar line
    terms: np.ndarray  # (M, 6) each ray's image about the ring centre: x(s) - centre x2(s) = a + s b


def affine_image(projector: CameraModel, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Homogeneous projector image point x(s) = alpha + s beta of the rays (each (M, 3))."""
    dev_o = projector.to_device(origins)
    dev_d = directions @ projector.R.T
    K = projector.K
    if projector.projection == "orthographic":  # x = (fx X + skew Y + cx, fy Y + cy, 1)
        M = K[:2, :2]
        alpha = np.column_stack([dev_o[:, :2] @ M.T + K[:2, 2], np.ones(len(dev_o))])
        beta = np.column_stack([dev_d[:, :2] @ M.T, np.zeros(len(dev_d))])
        return alpha, beta
    return dev_o @ K.T, dev_d @ K.T


def ray_cone(
    projector: CameraModel, origins: np.ndarray, directions: np.ndarray, radius: np.ndarray, center: tuple[float, float]
) -> ConeHits:
    """Intersect rays (M, 3) with the cones of rings of `radius` (M,) about `center` (pixels): with
    x(s) = alpha + s beta about the centre, the quadratic qa s^2 + 2 qb s + qc = 0 of the conic,
    its roots in front of camera and projector (one where it is nearly linear), and at each the
    projector angle, ds / dradius and the epipolar line's |cos| to the radial direction
    (rig.kernels.cone, a range of samples per thread)."""
    alpha, beta = affine_image(projector, origins, directions)
    count = len(radius)
    s, theta, ds_dradius, cos_beta = (np.empty((count, 2)) for _ in range(4))
    points, terms = np.empty((count, 2, 3)), np.empty((count, 6))
    arrays = (
        np.ascontiguousarray(alpha), np.ascontiguousarray(beta), np.asarray(radius, np.float64),
        (float(center[0]), float(center[1])), np.ascontiguousarray(origins, np.float64),
        np.ascontiguousarray(directions, np.float64), (s, points, theta, ds_dradius, cos_beta, terms),
    )  # fmt: skip
    list(pool().map(lambda span: _cone.cone_roots(*arrays, *span), batches(count)))
    return ConeHits(s=s, points=points, theta=theta, ds_dradius=ds_dradius, cos_beta=cos_beta, terms=terms)


def refine_on_distorted_ring(
    projector: CameraModel,
    origins: np.ndarray,
    directions: np.ndarray,
    s: np.ndarray,
    radius: np.ndarray,
    center: tuple[float, float],
    iterations: int = 4,
) -> np.ndarray:
    """Newton steps on |project(o + s d) - center| = radius with the full (distorted) projection,
    from the undistorted solution `s` (M,)."""
    c = np.asarray(center, dtype=np.float64)
    h = 1e-3
    s = s.copy()
    ok = np.isfinite(s)
    o, d, r = origins[ok], directions[ok], radius[ok]

    def residual(t: np.ndarray) -> np.ndarray:
        uv, _ = projector.project(o + t[:, None] * d)
        return np.linalg.norm(uv - c, axis=1) - r

    t = s[ok]
    for _ in range(iterations):
        slope = (residual(t + h) - residual(t - h)) / (2 * h)
        t = t - residual(t) / np.where(np.abs(slope) > 1e-12, slope, np.nan)
    s[ok] = t
    return s


def ray_half_plane(
    projector: CameraModel, origins: np.ndarray, directions: np.ndarray, theta: np.ndarray, center: tuple[float, float]
) -> np.ndarray:
    """Ray parameter s where each ray (M, 3) meets the projector's half-plane of polar angle `theta`
    (M, J) about `center`: the points the projector's (undistorted) image puts on the half-line from
    the centre at that angle. NaN where the ray meets only the other half, or behind either device."""
    u0, v0 = center
    alpha, beta = affine_image(projector, origins, directions)
    a = [alpha[:, 0:1] - u0 * alpha[:, 2:3], alpha[:, 1:2] - v0 * alpha[:, 2:3], alpha[:, 2:3]]
    b = [beta[:, 0:1] - u0 * beta[:, 2:3], beta[:, 1:2] - v0 * beta[:, 2:3], beta[:, 2:3]]
    sin, cos = np.sin(theta), np.cos(theta)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = -(a[0] * sin - a[1] * cos) / (b[0] * sin - b[1] * cos)
        along = (a[0] + s * b[0]) * cos + (a[1] + s * b[1]) * sin  # > 0 on the half-line at theta
        s[(s <= 0) | (a[2] + s * b[2] <= 0) | (along <= 0) | ~np.isfinite(s)] = np.nan
    return s
