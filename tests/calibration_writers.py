"""A camera-projector pair written as each tool writes its calibration, from the tools' own code or
documentation (rig.calibrate.formats and rig.calibrate.device_files name the sources): what the
readers' tests and bench/foreign_roundtrip.py read back."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.io import savemat


@dataclass(frozen=True)
class Pair:
    """Two devices' lenses and sizes (width, height), and X_projector = rotation X_camera + translation (mm)."""

    camera_k: np.ndarray
    camera_dist: np.ndarray
    camera_size: tuple[int, int]
    projector_k: np.ndarray
    projector_dist: np.ndarray
    projector_size: tuple[int, int]
    rotation: np.ndarray
    translation: np.ndarray
    board_to_camera: tuple[np.ndarray, np.ndarray] = field(
        default_factory=lambda: (cv2.Rodrigues(np.array([0.4, -0.1, 0.05]))[0], np.array([30.4, 54.5, 923.1]))
    )


def storage(path: Path, fields: dict[str, object]) -> Path:
    """An OpenCV FileStorage file of `fields`."""
    stored = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in fields.items():
        stored.write(key, value)
    stored.release()
    return path


def slstudio(folder: Path, pair: Pair) -> list[Path]:
    """CalibrationData::saveXML: cv::Matx matrices, kc/kp 5x1, sizes as ints."""
    return [
        storage(
            folder / "calibration.xml",
            {
                "Kc": pair.camera_k, "kc": pair.camera_dist.reshape(5, 1), "Kp": pair.projector_k,
                "kp": pair.projector_dist.reshape(5, 1), "Rp": pair.rotation, "Tp": pair.translation.reshape(3, 1),
                "stereo_error": 0.1, "frameWidth": pair.camera_size[0], "frameHeight": pair.camera_size[1],
                "screenResX": pair.projector_size[0], "screenResY": pair.projector_size[1],
            },
        )
    ]  # fmt: skip


def stereo_sample(folder: Path, pair: Pair) -> list[Path]:
    """samples/cpp/stereo_calib.cpp: intrinsics.yml and extrinsics.yml (sizes are not in them)."""
    intrinsics = {"M1": pair.camera_k, "D1": pair.camera_dist.reshape(1, 5), "M2": pair.projector_k}
    intrinsics["D2"] = pair.projector_dist.reshape(1, 5)
    extrinsics = {"R": pair.rotation, "T": pair.translation.reshape(3, 1), "R1": np.eye(3), "R2": np.eye(3)}
    return [storage(folder / "intrinsics.yml", intrinsics), storage(folder / "extrinsics.yml", extrinsics)]


def kalibr(folder: Path, pair: Pair) -> list[Path]:
    """A camchain.yaml (plain YAML, metres): cam0 the camera, cam1 the projector."""

    def camera(k: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> dict[str, Any]:
        intrinsics = [float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])]
        return {"camera_model": "pinhole", "intrinsics": intrinsics, "distortion_model": "radtan",
                "distortion_coeffs": [float(d) for d in dist[:4]], "resolution": list(size)}  # fmt: skip

    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = pair.rotation, pair.translation / 1000.0
    document = {
        "cam0": camera(pair.camera_k, pair.camera_dist, pair.camera_size),
        "cam1": {**camera(pair.projector_k, pair.projector_dist, pair.projector_size), "T_cn_cnm1": pose.tolist()},
    }
    (folder / "camchain.yaml").write_text(json.dumps(document))  # JSON is YAML: Kalibr's readers take it
    return [folder / "camchain.yaml"]


def matlab_struct(pair: Pair, new: bool) -> dict[str, Any]:
    """toStruct(stereoParams): before R2022b IntrinsicMatrix (K transposed) and MATLAB's row-vector
    rotation; from R2022b K. Pixel centres count from 1, sizes are [rows cols]."""

    def camera(k: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> dict[str, Any]:
        matlab_k = np.array(k, dtype=np.float64)
        matlab_k[:2, 2] += 1.0
        return {
            ("K" if new else "IntrinsicMatrix"): matlab_k if new else matlab_k.T,
            "RadialDistortion": [dist[0], dist[1], dist[4]],
            "TangentialDistortion": [dist[2], dist[3]],
            "ImageSize": [size[1], size[0]],
            "WorldUnits": "millimeters",
            "EstimateSkew": False,
        }

    return {
        "CameraParameters1": camera(pair.camera_k, pair.camera_dist, pair.camera_size),
        "CameraParameters2": camera(pair.projector_k, pair.projector_dist, pair.projector_size),
        "RotationOfCamera2": pair.rotation.T,  # x2 = x1 R + t with row vectors
        "TranslationOfCamera2": pair.translation,
    }


def matlab_mat(folder: Path, pair: Pair) -> list[Path]:
    """s = toStruct(stereoParams); save('stereo.mat', 's') (v7), as MATLAB before R2022b."""
    savemat(folder / "stereo.mat", {"s": matlab_struct(pair, new=False)})
    return [folder / "stereo.mat"]


def matlab_json(folder: Path, pair: Pair) -> list[Path]:
    """jsonencode(toStruct(stereoParams)), as MATLAB from R2022b."""
    document = json.loads(json.dumps(matlab_struct(pair, new=True), default=lambda a: np.asarray(a).tolist()))
    (folder / "stereo.json").write_text(json.dumps(document))
    return [folder / "stereo.json"]


def _ros_rows(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.15g}" for v in np.ravel(values)) + "]"


def ros_camera_info(
    path: Path, name: str, k: np.ndarray, dist: np.ndarray, size: tuple[int, int], r: np.ndarray, p: np.ndarray
) -> Path:
    """As camera_calibration_parsers writes a camera_info YAML: matrices as rows, cols and data."""
    path.write_text(
        f"image_width: {size[0]}\nimage_height: {size[1]}\ncamera_name: {name}\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: {_ros_rows(k)}\n"
        f"distortion_model: plumb_bob\n"
        f"distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: {_ros_rows(dist)}\n"
        f"rectification_matrix:\n  rows: 3\n  cols: 3\n  data: {_ros_rows(r)}\n"
        f"projection_matrix:\n  rows: 3\n  cols: 4\n  data: {_ros_rows(p)}\n"
    )
    return path


def ros_pair(folder: Path, pair: Pair) -> list[Path]:
    """A stereo pair's two files, rectified by OpenCV as ROS's calibrator does, lengths in metres."""
    r1, r2, p1, p2, *_ = cv2.stereoRectify(
        pair.camera_k, pair.camera_dist, pair.projector_k, pair.projector_dist, pair.camera_size,
        pair.rotation, pair.translation.reshape(3, 1) / 1000.0,
    )  # fmt: skip
    left = ros_camera_info(folder / "left.yaml", "rig/left", pair.camera_k, pair.camera_dist, pair.camera_size, r1, p1)
    right = ros_camera_info(
        folder / "right.yaml", "rig/right", pair.projector_k, pair.projector_dist, pair.projector_size, r2, p2
    )
    return [left, right]


def underworld_texts(folder: Path, k: np.ndarray, dist: np.ndarray, r: np.ndarray, t: np.ndarray) -> Path:
    """As 3DUNDERWORLD's exportMat writes them: a row per line, each value followed by a tab."""
    folder.mkdir(parents=True)
    for name, matrix in (
        ("cam_matrix.txt", k),
        ("cam_distortion.txt", dist.reshape(1, 5)),
        ("cam_rotation_matrix.txt", r),
        ("cam_trans_vectror.txt", t.reshape(3, 1)),
    ):
        (folder / name).write_text("".join("".join(f"{v:.15g}\t" for v in row) + "\n" for row in matrix))
    return folder


def underworld_xml(path: Path, k: np.ndarray, dist: np.ndarray, r: np.ndarray, t: np.ndarray, size: tuple[int, int]):
    """A 3DUNDERWORLD calib.xml: the Camera map as v4 reads it."""
    stored = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    stored.startWriteStruct("Camera", cv2.FILE_NODE_MAP)
    for key, value in (("Calibrated", 1), ("Matrix", k), ("Distortion", dist.reshape(1, 5))):
        stored.write(key, value)
    stored.write("Translation", t.reshape(3, 1))
    stored.write("Rotation", r)
    stored.write("Height", size[1])
    stored.write("Width", size[0])
    stored.endWriteStruct()
    stored.release()
    return path


def underworld_pair(folder: Path, pair: Pair) -> list[Path]:
    """The camera's four text files and the projector's calib.xml, both posed from one board."""
    rc, tc = pair.board_to_camera
    rp, tp = pair.rotation @ rc, pair.rotation @ tc + pair.translation
    camera = underworld_texts(folder / "camera", pair.camera_k, pair.camera_dist, rc, tc)
    return [camera, underworld_xml(folder / "calib.xml", pair.projector_k, pair.projector_dist, rp, tp,
                                   pair.projector_size)]  # fmt: skip


def opencv_sample(path: Path, k: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> Path:
    """As OpenCV's camera calibration tutorial sample saves its out_camera_data.xml."""
    return storage(
        path,
        {
            "nr_of_frames": 12, "image_width": size[0], "image_height": size[1], "board_width": 9,
            "board_height": 6, "square_size": 25.0, "camera_matrix": k, "distortion_coefficients": dist.reshape(5, 1),
            "avg_reprojection_error": 0.31,
        },
    )  # fmt: skip


def opencv_samples(folder: Path, pair: Pair) -> list[Path]:
    """Two of the sample's files and a third with R and T."""
    return [
        opencv_sample(folder / "camera.xml", pair.camera_k, pair.camera_dist, pair.camera_size),
        opencv_sample(folder / "projector.xml", pair.projector_k, pair.projector_dist, pair.projector_size),
        storage(folder / "extrinsics.yml", {"R": pair.rotation, "T": pair.translation.reshape(3, 1)}),
    ]


WRITERS: dict[str, Callable[[Path, Pair], list[Path]]] = {
    "SLStudio": slstudio,
    "OpenCV stereo sample": stereo_sample,
    "Kalibr camchain": kalibr,
    "MATLAB stereoParameters (.mat)": matlab_mat,
    "MATLAB stereoParameters (JSON)": matlab_json,
    "ROS camera_info": ros_pair,
    "3DUNDERWORLD": underworld_pair,
    "OpenCV camera calibration": opencv_samples,
}
