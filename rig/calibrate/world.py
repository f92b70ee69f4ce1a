"""The world frame a calibration is written in: the first view's board (its plane z = 0, x along
its columns; the default, and the simulated bench's own frame) or the first camera's (where other
systems put theirs). The first view's board, triangulated by the calibrated pair, is then checked
against where the chosen frame puts it."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Literal

import numpy as np

from rig.calibrate.boards import Board
from rig.calibrate.check import triangulate_corners
from rig.calibrate.solve import DeviceCalibration
from rig.calibrate.views import View
from rig.config import RigConfig
from rig.errors import CalibrationError

World = Literal["board", "camera"]


def reframed(devices: list[DeviceCalibration], world: World) -> tuple[list[DeviceCalibration], np.ndarray, np.ndarray]:
    """The devices posed in `world` (they come posed in the first view's board frame), and the
    board frame's place in it: X_world = R X_board + t."""
    if world == "board":
        return devices, np.eye(3), np.zeros(3)
    rotation, translation = np.asarray(devices[0].R, float), np.asarray(devices[0].t, float).ravel()
    moved = [
        dataclasses.replace(d, R=d.R @ rotation.T, t=np.ravel(d.t) - d.R @ rotation.T @ translation) for d in devices
    ]
    return moved, rotation, translation


def refuse_camera_world_for_the_bench(config: RigConfig, out: Path, world: World) -> None:
    """CalibrationError where a camera-frame calibration would replace the one a simulated rig scans
    with: the bench's truth is in the board's frame, and its scans would stop."""
    scanned = config.calibration.file
    if world != "camera" or not config.simulated or scanned is None:
        return
    folder = scanned.parent if scanned.suffix == ".json" else scanned
    if out.resolve() == folder.resolve():
        raise CalibrationError(
            f"world camera: {out} is the calibration the simulated bench scans with, whose truth is in the "
            "board's frame; write a camera-frame calibration elsewhere (--out)"
        )


def world_check(
    views: list[View],
    board: Board,
    camera: DeviceCalibration,
    projector: DeviceCalibration,
    board_in_world: tuple[np.ndarray, np.ndarray],
) -> dict[str, Any]:
    """The first view's board corners as the first camera and projector triangulate them, against
    where the world frame puts the board: rms and largest distance (mm), and how many corners."""
    first = next((v for v in views if v.index == 0), None)
    if first is None or 0 not in first.camera or (0, 0) not in first.projector:
        return {}
    corners = triangulate_corners(camera, projector, first.camera[0], first.projector[(0, 0)])
    if not corners:
        return {}
    ids = np.array(sorted(corners))
    rotation, translation = board_in_world
    expected = board.object_points(ids).astype(np.float64) @ rotation.T + translation
    distance = np.linalg.norm(np.array([corners[i] for i in ids]) - expected, axis=1)
    return {
        "corners": len(ids),
        "rms_mm": round(float(np.sqrt(np.mean(distance**2))), 4),
        "max_mm": round(float(distance.max()), 4),
    }
