"""OpenCV calibrations: each device's intrinsics (Zhang), then projectors against a camera
(stereo, intrinsics fixed), all in the world frame of the first view's board."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from rig.calibrate.boards import Board, Detection
from rig.calibrate.views import View
from rig.errors import CalibrationError

MIN_VIEWS = 3
MIN_CORNERS = 6
OUTLIER_FACTOR = 3.0  # a view whose RMS exceeds this many times the median is dropped
OUTLIER_FLOOR_PX = 0.5  # ... and exceeds this


@dataclass
class DeviceCalibration:
    """One device's calibrated model, world pose and quality."""

    name: str
    kind: str  # "camera" or "projector"
    resolution: tuple[int, int]
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray  # world -> device
    t: np.ndarray
    rms_px: float
    per_view_rms_px: dict[int, float]
    rejected: dict[int, str] = field(default_factory=dict)  # view -> reason
    stereo_rms_px: float | None = None
    points: dict[int, np.ndarray] = field(default_factory=dict)  # view -> image points, for coverage


def _intrinsics(
    name: str, size: tuple[int, int], detections: dict[int, Detection], board: Board, fix_k3: bool = True
) -> tuple[float, np.ndarray, np.ndarray, dict[int, tuple[np.ndarray, np.ndarray]], dict[int, float], dict[int, str]]:
    rejected: dict[int, str] = {}
    usable = {}
    for view, det in sorted(detections.items()):
        if len(det) < MIN_CORNERS:
            rejected[view] = f"only {len(det)} corners found (at least {MIN_CORNERS} needed)"
        else:
            usable[view] = det
    for _ in range(2):  # calibrate, drop outlier views once, calibrate again
        if len(usable) < MIN_VIEWS:
            raise CalibrationError(
                f"{name}: the board was found in {len(usable)} usable view(s); calibration needs at least "
                f"{MIN_VIEWS} (10-20 recommended)"
            )
        views = list(usable)
        obj = [board.object_points(usable[v].ids).astype(np.float32) for v in views]
        img = [usable[v].points.astype(np.float32).reshape(-1, 1, 2) for v in views]
        flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
        rms, K, dist, rvecs, tvecs, _, _, per_view = cv2.calibrateCameraExtended(
            obj, img, size, None, None, flags=flags
        )
        per_view_rms = {v: float(e) for v, e in zip(views, np.ravel(per_view), strict=True)}
        limit = max(OUTLIER_FACTOR * float(np.median(list(per_view_rms.values()))), OUTLIER_FLOOR_PX)
        outliers = {v: e for v, e in per_view_rms.items() if e > limit}
        if not outliers or len(usable) - len(outliers) < MIN_VIEWS:
            break
        for v, e in outliers.items():
            rejected[v] = f"reprojection error {e:.2f} px, more than {limit:.2f} px (outlier)"
            del usable[v]
    poses = {v: (cv2.Rodrigues(r)[0], np.ravel(t)) for v, r, t in zip(views, rvecs, tvecs, strict=True)}
    return float(rms), K, np.ravel(dist), poses, per_view_rms, rejected


def calibrate_cameras(
    views: list[View], board: Board, names: list[str], sizes: list[tuple[int, int]]
) -> list[DeviceCalibration]:
    out = []
    for c, (name, size) in enumerate(zip(names, sizes, strict=True)):
        detections = {v.index: v.camera[c] for v in views if c in v.camera}
        if not detections:
            raise CalibrationError(
                f"{name}: the board ({board.config.squares[0]}x{board.config.squares[1]} "
                f"{board.config.kind} squares) was not found in any view"
            )
        rms, K, dist, poses, per_view, rejected = _intrinsics(name, size, detections, board)
        if 0 not in poses:
            raise CalibrationError(
                f"{name}: the first view (the board that defines the world frame) was not usable: "
                f"{rejected.get(0, 'board not found')}"
            )
        R, t = poses[0]
        out.append(
            DeviceCalibration(
                name,
                "camera",
                size,
                K,
                dist,
                R,
                t,
                rms,
                per_view,
                rejected,
                points={v: d.points for v, d in detections.items()},
            )
        )
    return out


def calibrate_projectors(
    views: list[View], board: Board, cameras: list[DeviceCalibration], names: list[str], sizes: list[tuple[int, int]]
) -> list[DeviceCalibration]:
    out = []
    for p, (name, size) in enumerate(zip(names, sizes, strict=True)):
        # the camera that shares the most views with this projector anchors it
        counts = [sum((p, c) in v.projector for v in views) for c in range(len(cameras))]
        c = int(np.argmax(counts))
        camera = cameras[c]
        detections = {v.index: v.projector[(p, c)] for v in views if (p, c) in v.projector}
        if not detections:
            raise CalibrationError(
                f"{name}: no view gave projector coordinates at the board's corners "
                "(is the board lit by the projector, and inside its image?)"
            )
        rms, K, dist, _poses, per_view, rejected = _intrinsics(name, size, detections, board)
        common = [v for v in views if v.index in per_view and v.index not in rejected and c in v.camera]
        obj, cam_pts, proj_pts = [], [], []
        for v in common:
            proj = detections[v.index]
            cam = v.camera[c]
            shared, i_proj, i_cam = np.intersect1d(proj.ids, cam.ids, return_indices=True)
            if len(shared) < MIN_CORNERS:
                continue
            obj.append(board.object_points(shared).astype(np.float32))
            cam_pts.append(cam.points[i_cam].astype(np.float32).reshape(-1, 1, 2))
            proj_pts.append(proj.points[i_proj].astype(np.float32).reshape(-1, 1, 2))
        if len(obj) < MIN_VIEWS:
            raise CalibrationError(
                f"{name}: only {len(obj)} views show the board to both it and {camera.name}; "
                f"at least {MIN_VIEWS} needed"
            )
        stereo = cv2.stereoCalibrate(
            obj, cam_pts, proj_pts, camera.K, camera.dist, K, dist, camera.resolution, flags=cv2.CALIB_FIX_INTRINSIC
        )
        stereo_rms, R_cp, T_cp = stereo[0], stereo[5], np.ravel(stereo[6])
        R = R_cp @ camera.R
        t = R_cp @ camera.t + T_cp
        out.append(
            DeviceCalibration(
                name,
                "projector",
                size,
                K,
                dist,
                R,
                t,
                rms,
                per_view,
                rejected,
                stereo_rms_px=float(stereo_rms),
                points={v: d.points for v, d in detections.items()},
            )
        )
    return out
