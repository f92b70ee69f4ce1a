"""Calibration files as the common open systems write them (rig.calibrate.formats), each written
here from its tool's own code or documentation, read as they are: told apart by their fields, case
and all, split over several files, and slrig's own calibration.yaml."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from rig.calibrate.files import load_calibration, write_calibration
from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.calibrate.solve import DeviceCalibration
from rig.errors import CalibrationError
from tests.calibration_writers import storage as _storage
from tests.test_foreign_calibration import CAMERA_DIST, CAMERA_K, PROJECTOR_K, ROTATION, TRANSLATION


def _slstudio(path: Path, **extra: object) -> Path:
    """As SLStudio's CalibrationData::saveXML writes it: cv::Matx as matrices, kc/kp as 5x1, sizes as ints."""
    return _storage(
        path,
        {
            "Kc": CAMERA_K, "kc": CAMERA_DIST.reshape(5, 1), "Kp": PROJECTOR_K, "kp": np.zeros((5, 1)),
            "Rp": ROTATION, "Tp": TRANSLATION.reshape(3, 1), "cam_error": 0.21, "proj_error": 0.35,
            "stereo_error": 0.44, "frameWidth": 1280, "frameHeight": 1024, "screenResX": 912, "screenResY": 1140,
            **extra,
        },
    )  # fmt: skip


def test_slstudio_case_is_kept_apart_and_its_sizes_and_direction_are_its_own(tmp_path: Path) -> None:
    found = read_foreign_calibration(_slstudio(tmp_path / "calibration.xml"))
    assert found.format == "SLStudio" and found.extrinsics == "camera_to_projector" and found.unit == "mm"
    assert found.found["camera_matrix"] == "Kc" and found.found["camera_distortion"] == "kc"  # not one field
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
    assert np.allclose(found.projector.K, PROJECTOR_K) and np.allclose(found.projector.dist, 0.0)
    assert (found.camera.width, found.camera.height) == (1280, 1024)
    assert (found.projector.width, found.projector.height) == (912, 1140)
    assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    assert found.rms_px == pytest.approx(0.44)
    reversed_ = read_foreign_calibration(
        tmp_path / "calibration.xml", ForeignCalibrationOptions(extrinsics="projector_to_camera")
    )
    assert np.allclose(reversed_.projector.R, ROTATION.T)  # the options may say otherwise, and are obeyed
    bent = _slstudio(tmp_path / "bent.xml", kp=np.array([[0.05], [0.01], [0.0], [0.0], [0.0]]))
    assert np.allclose(read_foreign_calibration(bent).projector.dist[:2], [0.05, 0.01])
    plain = read_foreign_calibration(bent, ForeignCalibrationOptions(ignore_projector_distortion=True))
    assert np.allclose(plain.projector.dist, 0.0) and np.allclose(plain.camera.dist, CAMERA_DIST)


def test_opencvs_stereo_sample_is_read_from_its_two_files_together(tmp_path: Path) -> None:
    intrinsics = _storage(
        tmp_path / "intrinsics.yml",
        {"M1": CAMERA_K, "D1": CAMERA_DIST.reshape(1, 5), "M2": PROJECTOR_K, "D2": np.zeros((1, 5))},
    )
    extrinsics = _storage(
        tmp_path / "extrinsics.yml",
        {"R": ROTATION, "T": TRANSLATION.reshape(3, 1), "R1": np.eye(3), "R2": np.eye(3), "Q": np.eye(4)},
    )
    options = ForeignCalibrationOptions(camera_resolution=(1280, 1024), projector_resolution=(912, 1140))
    found = read_foreign_calibration([intrinsics, extrinsics], options)
    assert found.format == "OpenCV stereo sample"
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.projector.t, TRANSLATION)
    with pytest.raises(CalibrationError, match=r"missing \(looked for R, as OpenCV stereo sample\)"):
        read_foreign_calibration([intrinsics], options)
    twice = _storage(tmp_path / "again.yml", {"T": TRANSLATION.reshape(3, 1)})
    with pytest.raises(CalibrationError, match=r"again\.yml: T: also in .*extrinsics\.yml"):
        read_foreign_calibration([intrinsics, extrinsics, twice], options)


def test_a_file_with_two_systems_fields_is_refused_naming_both(tmp_path: Path) -> None:
    path = _slstudio(tmp_path / "mixed.xml", cam_int=CAMERA_K)
    with pytest.raises(CalibrationError, match="holds the fields of SLStudio and procam-calibration"):
        read_foreign_calibration(path)


def test_slrigs_own_calibration_yaml_reads_as_its_json(tmp_path: Path) -> None:
    projector_t = np.array([-180.0, 5.0, 20.0])
    camera = DeviceCalibration(
        "camera0", "camera", (1280, 1024), CAMERA_K, CAMERA_DIST, np.eye(3), np.zeros(3), 0.2, {}
    )
    projector = DeviceCalibration(
        "projector0", "projector", (912, 1140), PROJECTOR_K, np.zeros(5), ROTATION, projector_t, 0.3, {}
    )
    devices = [camera, projector]
    write_calibration(tmp_path, devices, {}, {})
    models, _ = load_calibration(tmp_path)
    found = read_foreign_calibration(tmp_path / "calibration.yaml")  # nested maps: no OpenCV assertion
    assert found.format == "slrig"
    for read, own in ((found.camera, models["camera0"]), (found.projector, models["projector0"])):
        assert (read.width, read.height) == (own.width, own.height)
        for a, b in ((read.K, own.K), (read.R, own.R), (read.t, own.t), (read.dist, own.dist)):
            assert np.allclose(a, b)
    from rig.service.reconstruct import calibration_models  # what `slrig reconstruct --calibration` reads

    by_yaml = calibration_models(tmp_path / "calibration.yaml", ForeignCalibrationOptions())
    by_json = calibration_models(tmp_path, ForeignCalibrationOptions())
    assert all(np.allclose(a.K, b.K) and np.allclose(a.t, b.t) for a, b in zip(by_yaml[:2], by_json[:2], strict=True))
    given = (ForeignCalibrationOptions(world="camera"), ForeignCalibrationOptions(translation_scale=1000.0))
    for options in given:  # even the camera, which is not slrig's world frame
        for source in (tmp_path / "calibration.yaml", tmp_path):  # not ignored silently, the YAML or the JSON
            with pytest.raises(CalibrationError, match="slrig's own calibration says these itself"):
                calibration_models(source, options)
    with pytest.raises(CalibrationError, match=r"has no device projector1 \(its: camera0, projector0"):
        read_foreign_calibration(tmp_path / "calibration.yaml", ForeignCalibrationOptions(projector="projector1"))


def test_calibration_show_prints_what_slrig_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.cli import main

    path = _slstudio(tmp_path / "calibration.xml")
    assert main(["calibration", "show", str(path), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["format"] == "SLStudio" and shown["extrinsics"] == "camera_to_projector" and shown["unit"] == "mm"
    assert shown["devices"]["camera0"]["resolution"] == [1280, 1024]
    assert shown["devices"]["projector0"]["resolution"] == [912, 1140]
    assert shown["baseline_mm"] == pytest.approx(float(np.linalg.norm(TRANSLATION)))
    assert shown["found"]["camera_distortion"] == "kc"
    assert main(["calibration", "show", str(path)]) == 0  # as text
    text = capsys.readouterr().out
    assert "SLStudio" in text and "projector projector0: 912x1140" in text and "camera_matrix <- Kc" in text
    # a file of names of its own, told by the command line; a wrong one refused naming file and field, exit 2
    own = _storage(tmp_path / "own.yml", {"A": CAMERA_K, "B": PROJECTOR_K, "rot": ROTATION, "tr": TRANSLATION})
    fields = "camera_matrix=A,projector_matrix=B,rotation=rot,translation=tr"
    sizes = ["--camera-resolution", "1280x1024", "--projector-resolution", "912x1140"]
    assert main(["calibration", "show", str(own), "--calibration-fields", fields, *sizes, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["found"]["camera_matrix"] == "A"
    assert main(["calibration", "show", str(own), "--calibration-fields", "camera_matrix", *sizes]) == 2
    assert "--calibration-fields: 'camera_matrix' is not FIELD=NAME" in capsys.readouterr().err
    broken = _slstudio(tmp_path / "broken.xml", Rp=ROTATION * 2)
    assert main(["calibration", "show", str(broken)]) == 2
    assert re.search(r"broken\.xml: Rp: not a rotation", capsys.readouterr().err)


KALIBR = """cam0:
  camera_model: pinhole
  intrinsics: [2400.0, 2401.5, 641.2, 509.8]
  distortion_model: radtan
  distortion_coeffs: [-0.12, 0.08, 0.001, -0.0005]
  rostopic: /cam0/image_raw
  resolution: [1280, 1024]
cam1:
  camera_model: pinhole
  intrinsics: [1800.0, 1800.0, 511.0, 700.0]
  distortion_model: radtan
  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, 0.21]
  - [0.0, 1.0, 0.0, -0.004]
  - [0.0, 0.0, 1.0, 0.035]
  - [0.0, 0.0, 0.0, 1.0]
  resolution: [912, 1140]
"""  # the layout of the Kalibr wiki's example camchain.yaml (plain YAML, not OpenCV's), in metres


def test_a_kalibr_camchain_reads_in_millimetres(tmp_path: Path) -> None:
    path = tmp_path / "camchain.yaml"
    path.write_text(KALIBR)
    found = read_foreign_calibration(path)
    assert found.format == "Kalibr camchain" and found.unit == "m"
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, [*CAMERA_DIST[:4], 0.0])
    assert (found.projector.width, found.projector.height) == (912, 1140)
    assert np.allclose(found.projector.t, [210.0, -4.0, 35.0])  # cam0 to cam1, metres as millimetres
    omni = tmp_path / "omni.yaml"
    omni.write_text(KALIBR.replace("camera_model: pinhole", "camera_model: omni", 1))
    with pytest.raises(CalibrationError, match=r"omni\.yaml: cam0\.camera_model: omni; slrig's devices are pinholes"):
        read_foreign_calibration(omni)


def test_a_file_no_parser_reads_is_refused_with_its_name_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rig.cli import main

    broken = tmp_path / "broken.xml"
    broken.write_text('<?xml version="1.0"?>\n<opencv_storage>\n<Kc>1 2')
    assert main(["calibration", "show", str(broken)]) == 2
    assert "broken.xml: not an OpenCV FileStorage file" in capsys.readouterr().err
    neither = tmp_path / "neither.yaml"
    neither.write_text("cam0: [1, 2\n  - x: }")
    assert main(["calibration", "show", str(neither)]) == 2
    assert "neither.yaml: neither OpenCV FileStorage" in capsys.readouterr().err
