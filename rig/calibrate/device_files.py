"""Calibration files that hold one device each, read as a pair: the first file's device is the
camera, the second's the projector; one alone is a camera (`slrig calibration show`).

- ROS camera_info (camera_calibration_parsers, sensor_msgs/CameraInfo): `image_width image_height
  camera_name camera_matrix distortion_model distortion_coefficients rectification_matrix
  projection_matrix`, matrices as {rows, cols, data} row by row. A stereo pair's relative pose is
  in its rectification: X_rect = R X_device, and the second device's P = [f' 0 c' Tx; 0 f' c'' Ty;
  0 0 1 0] with Tx = -f' B puts it at (Tx / f', Ty / f', 0) in the first's rectified frame; so
  X_second = R2^T (R1 X_first + t2 - t1). Lengths in metres (ROS's unit, REP 103).
- 3DUNDERWORLD-SLS: a camera's `calib.xml` (a `Camera` map: `Matrix Distortion Rotation
  Translation Width Height`) or the folder of its four text files (`cam_matrix.txt`,
  `cam_distortion.txt`, `cam_rotation_matrix.txt`, `cam_trans_vectror.txt`); the pose takes the
  shared board's frame to the camera's (solvePnP), in mm.
- OpenCV's camera calibration sample (samples/cpp/tutorial_code/calib3d/camera_calibration):
  `camera_matrix distortion_coefficients image_width image_height avg_reprojection_error`, no pose
  between devices: a third file gives R and T under the usual names.

A pair becomes flat fields under names that say where each came from, and a format whose names
are those, so the checks every calibration passes (rig.calibrate.foreign) are the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.calibrate.formats import GENERIC, CalibrationFormat
from rig.errors import CalibrationError

# name, where it is defined, its fields, how a pair's pose is found, its lengths' unit
DEVICE_FORMATS = (
    (
        "ROS camera_info",
        "ros-perception camera_calibration_parsers, sensor_msgs/CameraInfo",
        "image_width image_height camera_name camera_matrix distortion_model distortion_coefficients "
        "rectification_matrix projection_matrix",
        "from both files' rectification_matrix and projection_matrix",
        "m",
    ),
    (
        "3DUNDERWORLD",
        "theICTlab/3DUNDERWORLD-Structured-Light-Scanner (calib.xml; cam_*.txt)",
        "Camera.Matrix Camera.Distortion Camera.Rotation Camera.Translation Camera.Width Camera.Height or a "
        "folder of cam_matrix.txt cam_distortion.txt cam_rotation_matrix.txt cam_trans_vectror.txt",
        "from both devices' poses from the shared board",
        "mm",
    ),
    (
        "OpenCV camera calibration",
        "opencv samples/cpp/tutorial_code/calib3d/camera_calibration (out_camera_data.xml)",
        "camera_matrix distortion_coefficients image_width image_height avg_reprojection_error",
        "R and T from a third file, under the usual names",
        "the options' (translation_scale)",
    ),
)
ROS_MARKS = ("camera_matrix", "rectification_matrix", "projection_matrix")
OPENCV_SAMPLE_MARKS = ("camera_matrix", "distortion_coefficients", "avg_reprojection_error")
ROS_DISTORTION = ("plumb_bob", "rational_polynomial")  # OpenCV's order, 5 or 8 terms


@dataclass(frozen=True)
class DeviceFile:
    tool: str
    path: Path
    fields: dict[str, Any]  # field (rig.calibrate.formats.FIELDS, the camera's) -> value
    names: dict[str, str]  # field -> the file's name for it
    board_pose: tuple[Any, Any] | None = None  # (R, t) of the shared board's frame to the device's
    rectified: tuple[Any, Any] | None = None  # ROS: (rectification R, the device's place in metres)
    unit: str = "mm"


def device_file(path: Path, values: dict[str, Any]) -> DeviceFile | None:
    """The one device a file holds, where it is one of the formats above (None otherwise)."""
    if all(mark in values for mark in ROS_MARKS):
        return _ros(path, values)
    camera = values.get("Camera")
    if isinstance(camera, dict) and {"Matrix", "Rotation", "Translation"} <= camera.keys():
        return _underworld_xml(path, camera)
    if "cam_trans_vectror" in values:
        names = {"camera_matrix": "cam_matrix", "camera_distortion": "cam_distortion"}
        fields = {field: values[name] for field, name in names.items()}
        pose = (values["cam_rotation_matrix"], values["cam_trans_vectror"])
        return DeviceFile("3DUNDERWORLD", path, fields, names, board_pose=pose)
    if all(mark in values for mark in OPENCV_SAMPLE_MARKS):
        names = {
            "camera_matrix": "camera_matrix",
            "camera_distortion": "distortion_coefficients",
            "camera_width": "image_width",
            "camera_height": "image_height",
            "rms": "avg_reprojection_error",
        }
        return DeviceFile("OpenCV camera calibration", path, _present(values, names), _present_names(values, names))
    return None


def _present(values: dict[str, Any], names: dict[str, str]) -> dict[str, Any]:
    return {field: values[name] for field, name in names.items() if name in values}


def _present_names(values: dict[str, Any], names: dict[str, str]) -> dict[str, str]:
    return {field: name for field, name in names.items() if name in values}


def _ros(path: Path, values: dict[str, Any]) -> DeviceFile:
    model = values.get("distortion_model", "plumb_bob")
    if model not in ROS_DISTORTION:
        raise CalibrationError(
            f"calibration file {path}: distortion_model: {model}; slrig reads {' and '.join(ROS_DISTORTION)}"
        )
    names = {
        "camera_matrix": "camera_matrix",
        "camera_distortion": "distortion_coefficients",
        "camera_width": "image_width",
        "camera_height": "image_height",
    }
    projection = _numbers(path, "projection_matrix", values["projection_matrix"], 12).reshape(3, 4)
    rectification = _numbers(path, "rectification_matrix", values["rectification_matrix"], 9).reshape(3, 3)
    if projection[0, 0] <= 0 or projection[1, 1] <= 0:
        raise CalibrationError(f"calibration file {path}: projection_matrix: its focal lengths are not positive")
    place = np.array([projection[0, 3] / projection[0, 0], projection[1, 3] / projection[1, 1], 0.0])
    fields, found = _present(values, names), _present_names(values, names)
    return DeviceFile("ROS camera_info", path, fields, found, rectified=(rectification, place), unit="m")


def _underworld_xml(path: Path, camera: dict[str, Any]) -> DeviceFile:
    names = {
        "camera_matrix": "Matrix",
        "camera_distortion": "Distortion",
        "camera_width": "Width",
        "camera_height": "Height",
    }
    fields = _present(camera, names)
    found = {field: f"Camera.{name}" for field, name in _present_names(camera, names).items()}
    return DeviceFile("3DUNDERWORLD", path, fields, found, board_pose=(camera["Rotation"], camera["Translation"]))


def _numbers(path: Path, name: str, value: Any, size: int) -> np.ndarray:
    try:
        found = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise CalibrationError(f"calibration file {path}: {name}: not a matrix of numbers") from None
    if found.size != size or not np.all(np.isfinite(found)):
        raise CalibrationError(f"calibration file {path}: {name}: {found.size} values where {size} finite ones belong")
    return found


def paired(devices: list[DeviceFile], rest: dict[str, Any]) -> tuple[dict[str, Any], CalibrationFormat]:
    """The devices' files (and `rest`, the other files' fields) as flat fields and the format that
    names them: the camera's fields under `<file>: <name>`, the projector's too, and R, T derived
    (ROS, 3DUNDERWORLD) or read from `rest` (OpenCV's sample)."""
    if len(devices) > 2:
        listed = ", ".join(str(d.path) for d in devices)
        raise CalibrationError(
            f"calibration files {listed}: {len(devices)} devices; slrig reads a camera and a projector"
        )
    tools = {d.tool for d in devices}
    if len(tools) > 1:
        raise CalibrationError(f"calibration files: {' and '.join(sorted(tools))} files together; give one tool's")
    values: dict[str, Any] = {}
    names: dict[str, tuple[str, ...]] = {}
    for device, kind in zip(devices, ("camera", "projector"), strict=False):
        for field, value in device.fields.items():
            if field == "rms" and len(devices) > 1:  # one device's own error, not the pair's
                continue
            label = f"{device.path.name}: {device.names[field]}"
            values[label] = value
            names[field if field == "rms" else field.replace("camera", kind, 1)] = (label,)
    tool, unit = devices[0].tool, devices[0].unit
    scale: float | None = 1000.0 if unit == "m" else 1.0
    if len(devices) == 2:
        derived = _relative_pose(devices)
        if derived is not None:
            if rest:
                raise CalibrationError(f"calibration files: {', '.join(rest)}: {tool} files give the pose themselves")
            values["R (from both files)"], values["T (from both files)"] = derived
            names["rotation"], names["translation"] = ("R (from both files)",), ("T (from both files)",)
        else:
            values.update(rest)
            names["rotation"], names["translation"] = GENERIC.names["rotation"], GENERIC.names["translation"]
            unit, scale = GENERIC.unit, None
    elif rest:
        raise CalibrationError(f"calibration files: {', '.join(rest)}: beside a single device's file")
    chosen = CalibrationFormat(tool, "rig.calibrate.device_files", (), names, "camera_to_projector", unit, scale)
    return values, chosen


def _relative_pose(devices: list[DeviceFile]) -> tuple[np.ndarray, np.ndarray] | None:
    """R, T with X_projector = R X_camera + T, where the files say how the devices sit (None: they do not)."""
    first, second = devices
    if first.board_pose is not None and second.board_pose is not None:
        rc, tc = (np.asarray(v, dtype=np.float64) for v in first.board_pose)
        rp, tp = (np.asarray(v, dtype=np.float64) for v in second.board_pose)
        rotation = rp.reshape(3, 3) @ rc.reshape(3, 3).T
        return rotation, tp.ravel() - rotation @ tc.ravel()
    if first.rectified is not None and second.rectified is not None:
        (r1, t1), (r2, t2) = first.rectified, second.rectified
        return r2.T @ r1, r2.T @ (t2 - t1)
    return None
