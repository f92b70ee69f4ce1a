"""The dissertation's closed-form models for collimated (orthographic) ring projection.

These are the reconstructions of ../shared/reference/algorithms.md section 5, kept behind one small
interface so that the thesis's own equations can replace them. Each takes its parameters from the
calibration and states the geometric assumption it makes; where the rig violates it, the model is
wrong by the amount the violation implies (tests/test_ring_models.py measures it). The general,
assumption-free reconstruction is the ray-cone (ray-cylinder) intersection of rig.geometry.cone.
"""

from __future__ import annotations

import numpy as np

from rig.geometry.camera import CameraModel


def _projector_metric_ring(
    projector: CameraModel, center_px: tuple[float, float], radius_px: np.ndarray
) -> tuple[float, float, np.ndarray]:
    """Ring centre (X0, Y0) and radii in millimetres in the frame of an orthographic projector."""
    K = projector.K
    y0 = (center_px[1] - K[1, 2]) / K[1, 1]
    x0 = (center_px[0] - K[0, 2] - K[0, 1] * y0) / K[0, 0]
    return x0, y0, radius_px / K[0, 0]


def parallel_projection(
    camera: CameraModel,
    projector: CameraModel,
    camera_xy: np.ndarray,
    radius_px: np.ndarray,
    theta: np.ndarray,
    center_px: tuple[float, float],
) -> np.ndarray:
    """Ch.2, parallel projection (variant B): collimated projector, orthographic (telecentric)
    camera tilted by alpha about the projector's y axis.

    In the projector frame a ring point is (X0 + r cos t, Y0 + r sin t, Z). The camera sees
    x' = cos(a) X + sin(a) Z + m0 and y' = Y + m1 (millimetres), so t comes from y' (its branch
    from the decoded angle) and the depth Z from the deformation along x':
        Z = (x' - m0 - cos(a) X) / sin(a).
    cos(a), sin(a), m come from the calibration; the model assumes the camera has no other rotation
    relative to the projector (the cross terms it ignores are what a violation brings in).
    """
    if projector.projection != "orthographic" or camera.projection != "orthographic":
        raise ValueError("the parallel-projection model needs an orthographic projector and camera")
    M = camera.R[:2] @ projector.R.T  # projector frame -> camera image plane (mm)
    m = camera.t[:2] - M @ projector.t
    xy = camera.normalized(camera_xy)  # metric image coordinates of an orthographic camera
    x0, y0, r = _projector_metric_ring(projector, center_px, radius_px)
    Y = (xy[:, 1] - m[1]) / M[1, 1]
    sin_t = np.clip((Y - y0) / r, -1.0, 1.0)
    cos_t = np.where(np.cos(theta) >= 0, 1.0, -1.0) * np.sqrt(1.0 - sin_t**2)
    X = x0 + r * cos_t
    Z = (xy[:, 0] - m[0] - M[0, 0] * X) / M[0, 2]
    device = np.column_stack([X, Y, Z])
    return (device - projector.t) @ projector.R


def radius_ratio(
    camera: CameraModel,
    projector: CameraModel,
    camera_xy: np.ndarray,
    radius_px: np.ndarray,
    center_px: tuple[float, float],
) -> np.ndarray:
    """Ch.7, system function / radius ratio (Thales): collimated projector, pinhole camera on the
    rings' axis looking along it. A ring of radius r (mm) at depth Z images at normalized radius
    rho = r / Z about the image of the axis, so Z = r / rho: the ratio of output (observed) to input
    (projected) circle is the system function f / Z.

    The camera's pose enters only through the image of the axis; the model assumes the camera centre
    is on the axis (a camera off the axis sees rings that are not centred circles).
    """
    if projector.projection != "orthographic" or camera.projection != "pinhole":
        raise ValueError("the radius-ratio model needs an orthographic projector and a pinhole camera")
    _, _, r = _projector_metric_ring(projector, center_px, radius_px)  # the camera is assumed on the axis
    axis_cam = camera.R @ projector.axis  # direction of the rings' axis in the camera frame
    vanishing = axis_cam[:2] / axis_cam[2]
    xy = camera.normalized(camera_xy)
    rho = np.linalg.norm(xy - vanishing, axis=1)
    depth = r / np.where(rho > 1e-12, rho, np.nan)
    device = np.column_stack([xy * depth[:, None], depth])
    return (device - camera.t) @ camera.R
