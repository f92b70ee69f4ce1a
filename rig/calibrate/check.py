"""The board as a ruler: a calibration's camera-projector pair triangulates the board's corners of
every view, and what a printed board must be (squares of the size it was printed at, all in one
plane) measures the calibration in length units, independently of its reprojection errors."""

from __future__ import annotations

from typing import Any, Protocol

import cv2
import numpy as np

from rig.calibrate.boards import Board, Detection
from rig.calibrate.views import View


class Posed(Protocol):
    """A device model with its world pose (world -> device)."""

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray


def triangulate_corners(camera: Posed, projector: Posed, seen: Detection, lit: Detection) -> dict[int, np.ndarray]:
    """World positions of the corners both devices located, by corner id."""
    shared, i_cam, i_proj = np.intersect1d(seen.ids, lit.ids, return_indices=True)
    if len(shared) == 0:
        return {}
    rays = []
    for device, points in ((camera, seen.points[i_cam]), (projector, lit.points[i_proj])):
        normalised = cv2.undistortPoints(points.reshape(-1, 1, 2).astype(np.float64), device.K, device.dist)
        rays.append(normalised.reshape(-1, 2).T)
    projections = [np.hstack([d.R, np.reshape(d.t, (3, 1))]) for d in (camera, projector)]
    homogeneous = cv2.triangulatePoints(projections[0], projections[1], rays[0], rays[1])
    points = (homogeneous[:3] / homogeneous[3]).T
    return dict(zip(shared.tolist(), points, strict=True))


def board_check(
    camera: Posed, projector: Posed, views: list[tuple[Detection, Detection]], board: Board
) -> dict[str, Any]:
    """Per view and over all: the triangulated squares' mean side against the printed one (%) and
    the corners' rms distance to their plane (in the board's length unit)."""
    columns = board.inner[0]
    square = board.config.square_mm
    per_view, sides_all = [], []
    for seen, lit in views:
        corners = triangulate_corners(camera, projector, seen, lit)
        sides = [
            float(np.linalg.norm(corners[i] - corners[j]))
            for i in corners
            for j in (i + 1, i + columns)
            if j in corners and (j != i + 1 or (i + 1) % columns)
        ]
        if len(corners) < 4 or not sides:
            continue
        points = np.array(list(corners.values()))
        centred = points - points.mean(axis=0)
        normal = np.linalg.svd(centred, full_matrices=False)[2][2]
        per_view.append(
            {
                "square_error_pct": round(100 * (float(np.mean(sides)) / square - 1), 3),
                "plane_rms": round(float(np.sqrt(np.mean((centred @ normal) ** 2))), 4),
            }
        )
        sides_all += sides
    if not per_view:
        return {}
    return {
        "square": square,
        "square_error_pct": round(100 * (float(np.mean(sides_all)) / square - 1), 3),
        "worst_view_square_error_pct": max((v["square_error_pct"] for v in per_view), key=abs),
        "plane_rms": round(float(np.sqrt(np.mean([v["plane_rms"] ** 2 for v in per_view]))), 4),
        "views": per_view,
    }


def board_checks(views: list[View], board: Board, cameras: list[Posed], projectors: list[Posed]) -> dict[str, Any]:
    """board_check for every camera-projector pair that saw the board together, by "camera+projector"."""
    out = {}
    for p, projector in enumerate(projectors):
        for c, camera in enumerate(cameras):
            pairs = [(v.camera[c], v.projector[(p, c)]) for v in views if c in v.camera and (p, c) in v.projector]
            found = board_check(camera, projector, pairs, board) if pairs else {}
            if found:
                out[f"{getattr(camera, 'name', c)}+{getattr(projector, 'name', p)}"] = found
    return out
