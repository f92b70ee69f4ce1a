"""A camera ray against its ring's cone, one sample at a time (rig.geometry.cone.ray_cone): the
roots of the quadratic in the ray parameter and what triangulation reads at each, the same float64
steps as the array formulas they replace, in one pass instead of some sixty over every sample; a
range of samples per call, so rig.workers runs ranges on its threads."""

import math

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(**KERNEL, error_model="numpy")
def cone_roots(
    alpha: np.ndarray,
    beta: np.ndarray,
    radius: np.ndarray,
    centre: tuple[float, float],
    origins: np.ndarray,
    directions: np.ndarray,
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    start: int,
    stop: int,
) -> None:
    """Per sample i in [start, stop), the projector image point alpha[i] + s beta[i] (homogeneous)
    on the ring of `radius`[i] about `centre`: both roots s[i, k] (NaN where none lies in front of
    the camera and the projector; a near-linear quadratic has one), their world points, projector
    polar angles, ds / dradius, and |cos| of the angle between the ring's radial direction and the
    epipolar line; and the ray's image about the centre, terms[i] = (a0, a1, a2, b0, b1, b2).
    out = (s, points, theta, ds_dradius, cos_beta, terms)."""
    s, points, theta, ds_dradius, cos_beta, terms = out
    u0, v0 = centre
    nan = np.nan
    for i in range(start, stop):
        a0, a1, a2 = alpha[i, 0] - u0 * alpha[i, 2], alpha[i, 1] - v0 * alpha[i, 2], alpha[i, 2]
        b0, b1, b2 = beta[i, 0] - u0 * beta[i, 2], beta[i, 1] - v0 * beta[i, 2], beta[i, 2]
        terms[i, 0], terms[i, 1], terms[i, 2], terms[i, 3], terms[i, 4], terms[i, 5] = a0, a1, a2, b0, b1, b2
        r2 = radius[i] * radius[i]
        qa = b0 * b0 + b1 * b1 - r2 * b2 * b2
        qb = a0 * b0 + a1 * b1 - r2 * a2 * b2
        qc = a0 * a0 + a1 * a1 - r2 * a2 * a2
        disc = qb * qb - qa * qc
        root = math.sqrt(disc) if disc >= 0 else nan
        linear = abs(qa) < 1e-12 * (abs(qb) + 1e-300)
        for k in range(2):
            if linear:
                root_k = -qc / (2 * qb) if k == 0 else nan
            else:
                root_k = (-qb - root) / qa if k == 0 else (-qb + root) / qa
            x2 = a2 + root_k * b2
            if not (np.isfinite(root_k) and root_k > 0 and not x2 <= 0):
                root_k = nan
            s[i, k] = root_k
            x0, x1 = a0 + root_k * b0, a1 + root_k * b1
            theta[i, k] = math.atan2(x1 / x2, x0 / x2)
            ds_dradius[i, k] = radius[i] * x2 * x2 / (qa * root_k + qb)
            du = beta[i, 0] * x2 - (alpha[i, 0] + root_k * beta[i, 0]) * b2  # x2, b2: alpha's and beta's third
            dv = beta[i, 1] * x2 - (alpha[i, 1] + root_k * beta[i, 1]) * b2
            cos_beta[i, k] = abs(x0 * du + x1 * dv) / (math.hypot(x0, x1) * math.hypot(du, dv))
            for j in range(3):
                points[i, k, j] = origins[i, j] + root_k * directions[i, j]
