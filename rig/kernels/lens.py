"""Lens distortion inverted a point at a time (rig.geometry.camera.CameraModel._undistort): Newton's
method with the analytic Jacobian on the Brown-Conrady model, each point stopping once its own
residual is below the tolerance, in place of array steps that ran until the slowest point converged."""

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(**KERNEL, error_model="numpy")
def undistort(distorted: np.ndarray, dist: np.ndarray, iterations: int, tolerance: float, out: np.ndarray) -> None:
    """`out` (N, 2): the undistorted normalized coordinates whose distortion by `dist` (k1, k2, p1,
    p2, k3) is `distorted` (N, 2), within `tolerance`, after at most `iterations` Newton steps."""
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for i in range(distorted.shape[0]):
        xd, yd = distorted[i, 0], distorted[i, 1]
        x, y = xd, yd
        for _ in range(iterations):
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            rx = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xd
            ry = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - yd
            if not max(abs(rx), abs(ry)) >= tolerance:  # converged (or NaN: nothing to find)
                break
            d_radial = k1 + r2 * (2 * k2 + 3 * k3 * r2)
            a = radial + 2 * x * x * d_radial + 2 * p1 * y + 6 * p2 * x
            b = 2 * x * y * d_radial + 2 * p1 * x + 2 * p2 * y
            d = radial + 2 * y * y * d_radial + 6 * p1 * y + 2 * p2 * x
            det = a * d - b * b
            x, y = x - (d * rx - b * ry) / det, y - (a * ry - b * rx) / det
        out[i, 0], out[i, 1] = x, y
