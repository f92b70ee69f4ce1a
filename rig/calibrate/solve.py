"""OpenCV calibrations: each device's intrinsics (Zhang), then projectors against a camera
(stereo, intrinsics fixed), all in the world frame of the first view's board."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from rig.calibrate.boards import Board, Detection
from rig.calibrate.models import REFERENCE, LensFit, LensModel, choose, fit
from rig.calibrate.views import View
from rig.config import DeviceKind
from rig.errors import CalibrationError

MIN_VIEWS = 3
MIN_CORNERS = 6
OUTLIER_FACTOR = 3.0  # a view whose RMS exceeds this many times the median is dropped
OUTLIER_FLOOR_PX = 0.5  # ... and exceeds this


@dataclass
class DeviceCalibration:
    """One device's calibrated model, world pose and quality."""

    name: str
    kind: DeviceKind  # a camera or a projector
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
    model: str = REFERENCE
    std: dict[str, float] = field(default_factory=dict)  # free parameter -> its standard deviation
    held_out_px: dict[str, float] = field(default_factory=dict)  # model -> held-out rms, when chosen
    residuals: dict[int, np.ndarray] = field(default_factory=dict)  # view -> (N, 2) detected - reprojected, px


def _intrinsics(
    name: str, size: tuple[int, int], detections: dict[int, Detection], board: Board, model: str
) -> tuple[LensFit, dict[int, str]]:
    """The device's lens fitted to its usable views (outlier views dropped once, found with the
    reference model), then the requested model (or auto's choice) on the views that remain."""
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
        objects = {v: board.object_points(d.ids) for v, d in usable.items()}
        images = {v: d.points for v, d in usable.items()}
        lens = fit(LensModel(REFERENCE), objects, images, size)
        limit = max(OUTLIER_FACTOR * float(np.median(list(lens.per_view_rms_px.values()))), OUTLIER_FLOOR_PX)
        outliers = {v: e for v, e in lens.per_view_rms_px.items() if e > limit}
        if not outliers or len(usable) - len(outliers) < MIN_VIEWS:
            break
        for v, e in outliers.items():
            rejected[v] = f"reprojection error {e:.2f} px, more than {limit:.2f} px (outlier)"
            del usable[v]
    requested = LensModel.parse(model)
    return (lens if requested == lens.model else choose(requested, objects, images, size)), rejected


def _where(reason: str, view: View) -> str:
    """A dropped view's reason, with the folder it came from where it has one."""
    return f"{reason} ({view.label})" if view.label else reason


def calibrate_cameras(
    views: list[View], board: Board, names: list[str], sizes: list[tuple[int, int]], model: str = "auto"
) -> list[DeviceCalibration]:
    out = []
    for c, (name, size) in enumerate(zip(names, sizes, strict=True)):
        detections = {v.index: v.camera[c] for v in views if c in v.camera}
        if not detections:
            raise CalibrationError(
                f"{name}: the board ({board.config.squares[0]}x{board.config.squares[1]} "
                f"{board.config.kind} squares) was not found in any view"
            )
        lens, rejected = _intrinsics(name, size, detections, board, model)
        rejected |= {v.index: _where("board not found", v) for v in views if c not in v.camera}
        if 0 not in lens.poses:
            raise CalibrationError(
                f"{name}: the first view (the board that defines the world frame) was not usable: "
                f"{rejected.get(0, 'board not found')}"
            )
        R, t = lens.poses[0]
        out.append(_device(name, DeviceKind.CAMERA, size, lens, R, t, rejected, detections, board))
    return out


def calibrate_projectors(
    views: list[View],
    board: Board,
    cameras: list[DeviceCalibration],
    names: list[str],
    sizes: list[tuple[int, int]],
    model: str = "auto",
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
        lens, rejected = _intrinsics(name, size, detections, board, model)
        rejected |= {
            v.index: _where("board not found" if c not in v.camera else "no projector coordinates at its corners", v)
            for v in views
            if (p, c) not in v.projector
        }
        common = [v for v in views if v.index in lens.per_view_rms_px and v.index not in rejected and c in v.camera]
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
            obj,
            cam_pts,
            proj_pts,
            camera.K,
            camera.dist,
            lens.K,
            lens.dist,
            camera.resolution,
            flags=cv2.CALIB_FIX_INTRINSIC,
        )
        stereo_rms, R_cp, T_cp = stereo[0], stereo[5], np.ravel(stereo[6])
        R = R_cp @ camera.R
        t = R_cp @ camera.t + T_cp
        device = _device(name, DeviceKind.PROJECTOR, size, lens, R, t, rejected, detections, board)
        device.stereo_rms_px = float(stereo_rms)
        out.append(device)
    return out


def _device(
    name: str,
    kind: DeviceKind,
    size: tuple[int, int],
    lens: LensFit,
    R: np.ndarray,
    t: np.ndarray,
    rejected: dict[int, str],
    detections: dict[int, Detection],
    board: Board,
) -> DeviceCalibration:
    residuals = {}
    for view, (rotation, translation) in lens.poses.items():
        objects = board.object_points(detections[view].ids).astype(np.float64)
        rvec = cv2.Rodrigues(np.asarray(rotation, np.float64))[0]
        projected, _ = cv2.projectPoints(objects, rvec, np.asarray(translation, np.float64), lens.K, lens.dist)
        residuals[view] = detections[view].points - projected.reshape(-1, 2)
    return DeviceCalibration(
        name,
        kind,
        size,
        lens.K,
        lens.dist,
        R,
        t,
        lens.rms_px,
        lens.per_view_rms_px,
        rejected,
        points={v: d.points for v, d in detections.items()},
        model=lens.model.name,
        std=lens.std,
        held_out_px=lens.held_out_px,
        residuals=residuals,
    )
