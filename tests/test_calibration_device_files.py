"""Calibration files of one device each (ROS camera_info, 3DUNDERWORLD, OpenCV's camera
calibration sample) read as a camera-projector pair, and MATLAB's stereoParameters struct: each file
written here as its tool's documentation describes it, read back to the geometry it was made from."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.io import savemat

from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.errors import CalibrationError
from tests.test_calibration_formats import _storage
from tests.test_foreign_calibration import CAMERA_DIST, CAMERA_K, PROJECTOR_K, ROTATION, TRANSLATION

CAMERA_SIZE, PROJECTOR_SIZE = (1280, 1024), (912, 1140)


def _ros_rows(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.12g}" for v in np.ravel(values)) + "]"


def _ros(path: Path, name: str, k: np.ndarray, dist: np.ndarray, size: tuple[int, int], r: np.ndarray, p: np.ndarray):
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


def _ros_pair(folder: Path) -> tuple[Path, Path]:
    """A stereo pair's two files, rectified by OpenCV as ROS's calibrator does, lengths in metres."""
    r1, r2, p1, p2, *_ = cv2.stereoRectify(
        CAMERA_K, CAMERA_DIST, PROJECTOR_K, np.zeros(5), CAMERA_SIZE, ROTATION, TRANSLATION.reshape(3, 1) / 1000.0
    )
    left = _ros(folder / "left.yaml", "rig/left", CAMERA_K, CAMERA_DIST, CAMERA_SIZE, r1, p1)
    right = _ros(folder / "right.yaml", "rig/right", PROJECTOR_K, np.zeros(5), PROJECTOR_SIZE, r2, p2)
    return left, right


def test_two_ros_camera_infos_are_a_pair_posed_by_their_rectification(tmp_path: Path) -> None:
    left, right = _ros_pair(tmp_path)
    found = read_foreign_calibration([left, right])
    assert found.format == "ROS camera_info" and found.unit == "m"
    assert found.projector is not None
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
    assert (found.camera.width, found.camera.height) == CAMERA_SIZE
    assert (found.projector.width, found.projector.height) == PROJECTOR_SIZE
    assert np.allclose(found.projector.R, ROTATION, atol=1e-9)
    assert np.allclose(found.projector.t, TRANSLATION, atol=1e-6)  # metres read as millimetres
    assert found.found["camera_matrix"] == "left.yaml: camera_matrix"
    with pytest.raises(CalibrationError, match=r"left\.yaml: holds a camera alone .*give its file as well"):
        read_foreign_calibration([left])
    alone = read_foreign_calibration([left], single_device=True)
    assert alone.projector is None and np.allclose(alone.camera.K, CAMERA_K)
    fisheye = tmp_path / "fisheye.yaml"
    fisheye.write_text(left.read_text().replace("plumb_bob", "equidistant"))
    with pytest.raises(CalibrationError, match=r"fisheye\.yaml: distortion_model: equidistant"):
        read_foreign_calibration([fisheye, right])


def _underworld_texts(folder: Path, k: np.ndarray, dist: np.ndarray, r: np.ndarray, t: np.ndarray) -> Path:
    """As 3DUNDERWORLD's exportMat writes them: a row per line, each value followed by a tab."""
    folder.mkdir()
    for name, matrix in (
        ("cam_matrix.txt", k),
        ("cam_distortion.txt", dist.reshape(1, 5)),
        ("cam_rotation_matrix.txt", r),
        ("cam_trans_vectror.txt", t.reshape(3, 1)),
    ):
        (folder / name).write_text("".join("".join(f"{v:.12g}\t" for v in row) + "\n" for row in matrix))
    return folder


def test_3dunderworld_cameras_posed_from_one_board_are_a_pair(tmp_path: Path) -> None:
    board_to_camera = cv2.Rodrigues(np.array([0.4, -0.1, 0.05]))[0], np.array([30.4, 54.5, 923.1])
    board_to_projector = ROTATION @ board_to_camera[0], ROTATION @ board_to_camera[1] + TRANSLATION
    camera = _underworld_texts(tmp_path / "camera", CAMERA_K, CAMERA_DIST, *board_to_camera)
    storage = cv2.FileStorage(str(tmp_path / "calib.xml"), cv2.FILE_STORAGE_WRITE)
    storage.startWriteStruct("Camera", cv2.FILE_NODE_MAP)
    for key, value in (("Calibrated", 1), ("Matrix", PROJECTOR_K), ("Distortion", np.zeros((1, 5)))):
        storage.write(key, value)
    storage.write("Translation", board_to_projector[1].reshape(3, 1))
    storage.write("Rotation", board_to_projector[0])
    storage.write("Height", PROJECTOR_SIZE[1])
    storage.write("Width", PROJECTOR_SIZE[0])
    storage.endWriteStruct()
    storage.release()
    options = ForeignCalibrationOptions(camera_resolution=CAMERA_SIZE)  # the text files hold no size
    found = read_foreign_calibration([camera, tmp_path / "calib.xml"], options)
    assert found.format == "3DUNDERWORLD" and found.projector is not None
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
    assert (found.projector.width, found.projector.height) == PROJECTOR_SIZE
    assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    with pytest.raises(CalibrationError, match=r"camera_size: missing .* give camera_resolution"):
        read_foreign_calibration([camera, tmp_path / "calib.xml"])
    (camera / "cam_trans_vectror.txt").unlink()
    with pytest.raises(CalibrationError, match=r"camera: not 3DUNDERWORLD's four text files \(missing cam_trans"):
        read_foreign_calibration([camera, tmp_path / "calib.xml"], options)


def _opencv_sample(path: Path, k: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> Path:
    """As OpenCV's camera calibration tutorial sample saves its out_camera_data.xml."""
    return _storage(
        path,
        {
            "nr_of_frames": 12, "image_width": size[0], "image_height": size[1], "board_width": 9,
            "board_height": 6, "square_size": 25.0, "camera_matrix": k, "distortion_coefficients": dist.reshape(5, 1),
            "avg_reprojection_error": 0.31,
        },
    )  # fmt: skip


def test_opencv_camera_samples_are_a_pair_with_a_third_file_for_their_pose(tmp_path: Path) -> None:
    camera = _opencv_sample(tmp_path / "camera.xml", CAMERA_K, CAMERA_DIST, CAMERA_SIZE)
    projector = _opencv_sample(tmp_path / "projector.xml", PROJECTOR_K, np.zeros(5), PROJECTOR_SIZE)
    pose = _storage(tmp_path / "extrinsics.yml", {"R": ROTATION, "T": TRANSLATION.reshape(3, 1)})
    found = read_foreign_calibration([camera, projector, pose])
    assert found.format == "OpenCV camera calibration" and found.projector is not None
    assert found.found["rotation"] == "R" and found.rms_px is None  # one device's error is not the pair's
    assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    assert (found.projector.width, found.projector.height) == PROJECTOR_SIZE
    with pytest.raises(CalibrationError, match=r"rotation: missing \(looked for R, rotation"):
        read_foreign_calibration([camera, projector])
    alone = read_foreign_calibration([camera], single_device=True)
    assert alone.rms_px == pytest.approx(0.31)


def _matlab_struct(new: bool) -> dict[str, object]:
    """toStruct(stereoParams): before R2022b IntrinsicMatrix (K transposed) and MATLAB's row-vector
    rotation; from R2022b K. Pixel centres count from 1, sizes are [rows cols]."""

    def camera(k: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> dict[str, object]:
        matlab_k = k.copy()
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
        "CameraParameters1": camera(CAMERA_K, CAMERA_DIST, CAMERA_SIZE),
        "CameraParameters2": camera(PROJECTOR_K, np.zeros(5), PROJECTOR_SIZE),
        "RotationOfCamera2": ROTATION.T,  # x2 = x1 R + t with row vectors
        "TranslationOfCamera2": TRANSLATION,
    }


def test_matlab_stereo_parameters_read_from_a_mat_file_and_from_json(tmp_path: Path) -> None:
    savemat(tmp_path / "stereo.mat", {"s": _matlab_struct(new=False)})
    document = _matlab_struct(new=True)
    document = json.loads(json.dumps(document, default=lambda a: np.asarray(a).tolist()))
    (tmp_path / "stereo.json").write_text(json.dumps(document))
    for name in ("stereo.mat", "stereo.json"):
        found = read_foreign_calibration(tmp_path / name)
        assert found.format == "MATLAB stereoParameters" and found.unit == "millimeters" and found.projector
        assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
        assert (found.camera.width, found.camera.height) == CAMERA_SIZE
        assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    document["CameraParameters1"]["WorldUnits"] = "cm"
    (tmp_path / "cm.json").write_text(json.dumps(document))
    assert np.allclose(read_foreign_calibration(tmp_path / "cm.json").projector.t, TRANSLATION * 10)
    document["CameraParameters1"]["WorldUnits"] = "furlongs"
    (tmp_path / "odd.json").write_text(json.dumps(document))
    with pytest.raises(CalibrationError, match=r"CameraParameters1\.WorldUnits: 'furlongs' is not a unit"):
        read_foreign_calibration(tmp_path / "odd.json")
    document["CameraParameters1"]["K"][0][1] = 3.0
    (tmp_path / "skew.json").write_text(json.dumps(document))
    with pytest.raises(CalibrationError, match=r"CameraParameters1\.K: a skew of 3"):
        read_foreign_calibration(tmp_path / "skew.json", ForeignCalibrationOptions(translation_scale=1.0))


def test_calibration_show_prints_a_camera_alone_and_a_pair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.cli import main

    left, right = _ros_pair(tmp_path)
    assert main(["calibration", "show", str(left)]) == 0
    out = capsys.readouterr().out
    assert "ROS camera_info; its lengths in m" in out and "a camera alone: no projector, no baseline" in out
    assert main(["calibration", "show", str(left), str(right), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["baseline_mm"] == pytest.approx(float(np.linalg.norm(TRANSLATION)), abs=1e-4)
    assert [d["kind"] for d in shown["devices"].values()] == ["camera", "projector"]
    patterns = tmp_path / "patterns.yaml"
    patterns.write_text("projector: {resolution: [912, 1140]}\ngray: {axes: [columns, rows]}\n")
    command = ["reconstruct", str(tmp_path), "--patterns", str(patterns), "--calibration", str(left)]
    assert main([*command, "--out", str(tmp_path / "o")]) == 2
    assert "holds a camera alone" in capsys.readouterr().err
