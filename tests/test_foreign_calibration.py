"""Calibrations other tools wrote (OpenCV FileStorage XML/YAML, JSON): read into device models in
either extrinsics convention and world frame, and refused with the field named where they are wrong."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from rig.calibrate.foreign import ForeignCalibrationOptions, check_resolution, read_foreign_calibration
from rig.errors import CalibrationError
from tests.conftest import shared_data

CAMERA_K = np.array([[2400.0, 0.0, 641.2], [0.0, 2401.5, 509.8], [0.0, 0.0, 1.0]])
PROJECTOR_K = np.array([[1800.0, 0.0, 511.0], [0.0, 1800.0, 700.0], [0.0, 0.0, 1.0]])
CAMERA_DIST = np.array([-0.12, 0.08, 0.001, -0.0005, 0.0])
ROTATION = cv2.Rodrigues(np.array([[0.02], [-0.31], [0.05]]))[0]  # camera -> projector
TRANSLATION = np.array([210.0, -4.0, 35.0])  # mm


def _fields(**changes: Any) -> dict[str, Any]:
    fields: dict[str, Any] = {
        "img_shape": np.array([[1024.0], [1280.0]]),  # rows, cols
        "rms": 0.41,
        "cam_int": CAMERA_K,
        "cam_dist": CAMERA_DIST.reshape(1, 5),
        "proj_int": PROJECTOR_K,
        "proj_dist": np.zeros((1, 5)),
        "roration": ROTATION,
        "translation": TRANSLATION.reshape(3, 1),
    }
    fields.update(changes)
    return {k: v for k, v in fields.items() if v is not None}


def _write_storage(path: Path, fields: dict[str, Any]) -> Path:
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in fields.items():
        storage.write(key, value if isinstance(value, np.ndarray) else float(value))
    storage.release()
    return path


@pytest.mark.parametrize("suffix", [".xml", ".yaml"])
def test_an_opencv_file_gives_the_models_it_holds(tmp_path: Path, suffix: str) -> None:
    path = _write_storage(tmp_path / f"calibration{suffix}", _fields())
    found = read_foreign_calibration(path, ForeignCalibrationOptions(projector_resolution=(1024, 768)))
    camera, projector = found.camera, found.projector
    assert (camera.width, camera.height) == (1280, 1024) and (projector.width, projector.height) == (1024, 768)
    assert np.allclose(camera.K, CAMERA_K) and np.allclose(camera.dist, CAMERA_DIST)
    assert np.allclose(camera.R, np.eye(3)) and np.allclose(camera.t, 0.0)
    assert np.allclose(projector.R, ROTATION) and np.allclose(projector.t, TRANSLATION)
    assert found.rms_px == pytest.approx(0.41) and found.found["rotation"] == "roration"
    # the projector's centre seen from the camera: where the baseline says
    assert np.allclose(projector.center, -ROTATION.T @ TRANSLATION)


def test_the_other_direction_and_world_frame_describe_the_same_rig(tmp_path: Path) -> None:
    """R, T stored projector-to-camera and the projector as the world: the same relative pose."""
    inverse_r, inverse_t = ROTATION.T, -ROTATION.T @ TRANSLATION
    path = _write_storage(tmp_path / "c.yml", _fields(roration=inverse_r, translation=inverse_t.reshape(3, 1)))
    options = ForeignCalibrationOptions(
        extrinsics="projector_to_camera", world="projector", projector_resolution=(1024, 768), translation_scale=1.0
    )
    found = read_foreign_calibration(path, options)
    assert np.allclose(found.projector.R, np.eye(3)) and np.allclose(found.projector.t, 0.0)
    relative_r = found.projector.R @ found.camera.R.T  # camera -> projector
    relative_t = found.projector.t - relative_r @ found.camera.t
    assert np.allclose(relative_r, ROTATION) and np.allclose(relative_t, TRANSLATION)


def test_a_json_file_of_lists_or_opencv_matrices_and_metres(tmp_path: Path) -> None:
    document = {
        "camera_matrix": CAMERA_K.tolist(),
        "camera_distortion": CAMERA_DIST[:4].tolist(),  # 4 coefficients: k3 = 0
        "projector_matrix": {
            "type_id": "opencv-matrix",
            "rows": 3,
            "cols": 3,
            "dt": "d",
            "data": PROJECTOR_K.ravel().tolist(),
        },
        "R": cv2.Rodrigues(ROTATION)[0].ravel().tolist(),  # a rotation vector
        "T": (TRANSLATION / 1000.0).tolist(),
        "image_size": [1280, 1024],  # width, height
        "projector_size": [1024, 768],
    }
    path = tmp_path / "calib.json"
    path.write_text(json.dumps(document))
    found = read_foreign_calibration(path, ForeignCalibrationOptions(translation_scale=1000.0))
    assert (found.camera.width, found.camera.height) == (1280, 1024)
    assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    assert np.allclose(found.camera.dist, [*CAMERA_DIST[:4], 0.0]) and found.rms_px is None


@pytest.mark.parametrize(
    ("changes", "options", "message"),
    [
        ({"roration": ROTATION * 1.1}, {}, "roration: not a rotation"),
        ({"roration": ROTATION @ np.diag([1.0, 1.0, -1.0])}, {}, "roration: not a rotation"),
        ({"proj_int": None}, {}, "holds a camera alone (no projector_matrix: looked for proj_int"),
        ({"cam_dist": np.zeros((1, 6))}, {}, "cam_dist: 6 coefficients"),
        ({"cam_dist": np.array([[0.1, 0.0, 0.0, 0.0, 0.0, 0.02, 0.0, 0.0]])}, {}, "cam_dist: terms beyond k1"),
        ({"cam_int": np.eye(2)}, {}, "cam_int: 4 values where a 3x3 matrix has 9"),
        ({"translation": np.array([[1.0], [np.inf], [0.0]])}, {}, "translation: holds a value that is not a finite"),
        ({"R": ROTATION}, {}, "rotation: given twice, as R and roration"),
        ({}, {"projector_resolution": None}, "projector_size: missing"),
        ({}, {"camera_resolution": (640, 480)}, "img_shape: 1280x1024 in the file, 640x480 in the options"),
    ],
)
def test_a_wrong_calibration_is_refused_naming_the_field(
    tmp_path: Path, changes: dict[str, Any], options: dict[str, Any], message: str
) -> None:
    path = _write_storage(tmp_path / "c.xml", _fields(**changes))
    chosen = {"projector_resolution": (1024, 768), **options}
    with pytest.raises(CalibrationError, match="calibration file .*" + re.escape(message)):
        read_foreign_calibration(path, ForeignCalibrationOptions(**chosen))


def test_the_options_and_the_file_kind_are_checked(tmp_path: Path) -> None:
    path = _write_storage(tmp_path / "c.xml", _fields())
    named = _write_storage(tmp_path / "named.xml", _fields(pose=ROTATION.T))  # R under a name of its own
    options = ForeignCalibrationOptions(projector_resolution=(1024, 768), keys={"rotation": "pose"})
    assert np.allclose(read_foreign_calibration(named, options).projector.R, ROTATION.T)
    with pytest.raises(CalibrationError, match="unknown fields colour"):
        read_foreign_calibration(path, ForeignCalibrationOptions(keys={"colour": "x"}))
    other = tmp_path / "c.ini"
    other.write_text("K = 1")
    with pytest.raises(CalibrationError, match=r"not \.xml, \.yml, \.yaml, \.json or \.mat"):
        read_foreign_calibration(other)
    broken = tmp_path / "c.json"
    broken.write_text("{")
    with pytest.raises(CalibrationError, match="not JSON"):
        read_foreign_calibration(broken)
    found = read_foreign_calibration(path, ForeignCalibrationOptions(projector_resolution=(1024, 768)))
    with pytest.raises(CalibrationError, match="camera is calibrated for 1280x1024, the frames are 640x512"):
        check_resolution(found.camera, (640, 512), "camera", "the frames are", path)


def test_the_procam_calibration_result_reads_as_its_authors_wrote_it() -> None:
    """kamino410/procam-calibration's calibration_result.xml: a real camera (1280x1024) and
    projector (1024x768, not in the file), R, T of the projector relative to the camera."""
    path = shared_data("procam-calibration", "sample_data", "calibration_result.xml")
    found = read_foreign_calibration(path, ForeignCalibrationOptions(projector_resolution=(1024, 768)))
    assert (found.camera.width, found.camera.height) == (1280, 1024)  # img_shape is (rows, cols)
    assert found.camera.K[0, 0] == pytest.approx(3452.39, abs=0.01)
    assert found.projector.K[1, 2] == pytest.approx(1357.83, abs=0.01)  # the lens shift of a DLP projector
    assert found.rms_px == pytest.approx(0.857, abs=0.001)
    assert np.linalg.norm(found.projector.center) == pytest.approx(644.6, abs=0.5)  # the baseline, in their unit
    assert found.found == {
        "camera_matrix": "cam_int",
        "camera_distortion": "cam_dist",
        "projector_matrix": "proj_int",
        "projector_distortion": "proj_dist",
        "rotation": "roration",
        "translation": "translation",
        "camera_size": "img_shape",
        "rms": "rms",
    }
