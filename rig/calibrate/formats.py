"""The calibration files of the common open systems, told apart by what they hold: each format's
own field names, exact (SLStudio's `Kc` is the camera matrix and its `kc` the camera's
distortion), what its R, T map and in which unit, as its tool defines them.

- SLStudio (jakobwilm/slstudio, `CalibrationData::saveXML`): `Kc kc Kp kp Rp Tp`, the camera's
  `frameWidth frameHeight`, the projector's `screenResX screenResY`, `stereo_error`; its
  triangulation projects with `Kp [Rp | Tp]` from the camera's frame: camera to projector; mm.
- procam-calibration (kamino410/procam-calibration): `cam_int cam_dist proj_int proj_dist`,
  `roration` [sic] and `translation` as OpenCV's stereoCalibrate returns them (camera to
  projector), `img_shape` (rows, cols), `rms`; the unit of its board.
- OpenCV's stereo sample (samples/cpp/stereo_calib.cpp): `M1 D1 M2 D2` in intrinsics.yml and
  `R T` in extrinsics.yml (often read together: several files are one calibration), device 1 to
  device 2 as stereoCalibrate; device 1 is taken for the camera.
- Kalibr (ethz-asl/kalibr wiki, "yaml formats"): a camchain YAML with a map per camera, `cam0`
  (taken for the camera) and `cam1` (the projector), each with `intrinsics` [fu fv pu pv] of a
  `pinhole` model, `distortion_coeffs` of `radtan` (k1 k2 p1 p2, OpenCV's order) and `resolution`
  [width, height]; `cam1.T_cn_cnm1` takes cam0's coordinates to cam1's; metres.
- MATLAB's stereoParameters (Computer Vision Toolbox), as `toStruct` gives it saved to a .mat
  (-v7) or JSON: `CameraParameters1` (the camera) and `CameraParameters2` (the projector), each
  with `K` (or, before R2022b, `IntrinsicMatrix`, its transpose), `RadialDistortion`,
  `TangentialDistortion`, `ImageSize` [rows cols] and `WorldUnits`; `RotationOfCamera2` and
  `TranslationOfCamera2` in MATLAB's row-vector convention (x2 = x1 R + t), or a `PoseCamera2`
  (camera 2 to camera 1). MATLAB counts pixels from 1: its principal point is 1 more than OpenCV's.
  Read as MATLAB's stereoParametersToOpenCV does (R transposed, principal points less 1).
- Files of one device each (ROS camera_info, 3DUNDERWORLD, OpenCV's camera calibration sample):
  rig.calibrate.device_files.
- slrig's own calibration.yaml: a map per device with its `kind`, `image_width`,
  `image_height`, `camera_matrix`, `distortion_coefficients` and pose from the world.
- Anything else: each field under its usual names (`GENERIC`), exact too, or under the name the
  options give (`--calibration-fields camera_matrix=K,...`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

Direction = Literal["camera_to_projector", "projector_to_camera"]

FIELDS = (
    "camera_matrix",
    "camera_distortion",
    "projector_matrix",
    "projector_distortion",
    "rotation",
    "translation",
    "camera_size",
    "projector_size",
    "camera_width",
    "camera_height",
    "projector_width",
    "projector_height",
    "rms",
)


@dataclass(frozen=True)
class CalibrationFormat:
    name: str
    source: str  # where its names and conventions are defined
    marks: tuple[str, ...]  # fields whose presence, all of them, says a file is in this format
    names: dict[str, tuple[str, ...]]  # field -> the format's names for it
    extrinsics: Direction | None  # what its R, T map, where the format says; None: the options'
    unit: str  # its lengths' unit, as its tool defines it
    scale_mm: float | None = None  # millimetres per unit where the format fixes its unit
    unit_field: str | None = None  # the field naming the unit, where the file says it
    rows_first: tuple[str, ...] = ()  # sizes stored (rows, columns); others (and any *shape*) are (width, height)


GENERIC = CalibrationFormat(
    "generic",
    "the usual names of other scripts",
    (),
    {
        "camera_matrix": ("camera_matrix", "cameraMatrix", "cam_k", "cam_mtx", "cam_matrix", "camera_intrinsics", "K1"),
        "camera_distortion": ("camera_distortion", "cam_distortion", "dist_coeffs", "distCoeffs", "cam_dist_coeffs"),
        "projector_matrix": ("projector_matrix", "proj_k", "proj_mtx", "proj_matrix", "projector_intrinsics", "K2"),
        "projector_distortion": ("projector_distortion", "proj_distortion", "proj_dist_coeffs"),
        "rotation": ("R", "rotation", "rot", "rotation_matrix", "om", "rvec"),
        "translation": ("T", "translation", "trans", "tvec", "translation_vector"),
        "camera_size": ("image_size", "imageSize", "camera_size", "camera_resolution", "cam_shape"),
        "projector_size": ("projector_size", "proj_size", "projector_resolution", "proj_shape"),
        "camera_width": ("image_width",),
        "camera_height": ("image_height",),
        "rms": ("rms", "reprojection_error", "rms_error", "stereo_rms"),
    },
    None,
    "the options' (translation_scale)",
)

FORMATS = (
    CalibrationFormat(
        "SLStudio",
        "jakobwilm/slstudio src/calibrator/CalibrationData.cpp (saveXML, loadXML)",
        ("Kc",),
        {
            "camera_matrix": ("Kc",),
            "camera_distortion": ("kc",),
            "projector_matrix": ("Kp",),
            "projector_distortion": ("kp",),
            "rotation": ("Rp",),
            "translation": ("Tp",),
            "camera_width": ("frameWidth",),
            "camera_height": ("frameHeight",),
            "projector_width": ("screenResX",),
            "projector_height": ("screenResY",),
            "rms": ("stereo_error",),
        },
        "camera_to_projector",
        "mm",
        1.0,
    ),
    CalibrationFormat(
        "procam-calibration",
        "kamino410/procam-calibration calibrate.py (calibration_result.xml)",
        ("cam_int",),
        {
            "camera_matrix": ("cam_int",),
            "camera_distortion": ("cam_dist",),
            "projector_matrix": ("proj_int",),
            "projector_distortion": ("proj_dist",),
            "rotation": ("R", "roration", "rotation"),
            "translation": ("translation", "T"),
            "camera_size": ("img_shape",),
            "projector_size": ("proj_shape",),
            "rms": ("rms",),
        },
        "camera_to_projector",
        "its board's",
    ),
    CalibrationFormat(
        "OpenCV stereo sample",
        "opencv samples/cpp/stereo_calib.cpp (intrinsics.yml, extrinsics.yml)",
        ("M1",),
        {
            "camera_matrix": ("M1",),
            "camera_distortion": ("D1",),
            "projector_matrix": ("M2",),
            "projector_distortion": ("D2",),
            "rotation": ("R",),
            "translation": ("T",),
        },
        "camera_to_projector",
        "its board's",
    ),
)


KALIBR = CalibrationFormat(
    "Kalibr camchain",
    "ethz-asl/kalibr wiki, yaml formats (camchain.yaml)",
    ("cam0.intrinsics", "cam1.intrinsics"),
    {
        "camera_matrix": ("cam0.intrinsics",),
        "camera_distortion": ("cam0.distortion_coeffs",),
        "camera_size": ("cam0.resolution",),
        "projector_matrix": ("cam1.intrinsics",),
        "projector_distortion": ("cam1.distortion_coeffs",),
        "projector_size": ("cam1.resolution",),
        "rotation": ("cam1.T_cn_cnm1.R",),
        "translation": ("cam1.T_cn_cnm1.t",),
    },
    "camera_to_projector",
    "m",
    1000.0,
)
MATLAB = CalibrationFormat(
    "MATLAB stereoParameters",
    "MathWorks Computer Vision Toolbox: toStruct(stereoParams), saved -v7 or jsonencode'd (stereoParametersToOpenCV)",
    ("CameraParameters1.ImageSize", "CameraParameters2.ImageSize"),
    {
        "camera_matrix": ("CameraParameters1.K",),
        "camera_distortion": ("CameraParameters1.RadialDistortion+TangentialDistortion",),
        "camera_size": ("CameraParameters1.ImageSize",),
        "projector_matrix": ("CameraParameters2.K",),
        "projector_distortion": ("CameraParameters2.RadialDistortion+TangentialDistortion",),
        "projector_size": ("CameraParameters2.ImageSize",),
        "rotation": ("RotationOfCamera2'", "PoseCamera2.R'"),
        "translation": ("TranslationOfCamera2", "-PoseCamera2.R' Translation"),
    },
    "camera_to_projector",
    "its WorldUnits",
    unit_field="CameraParameters1.WorldUnits",
    rows_first=("CameraParameters1.ImageSize", "CameraParameters2.ImageSize"),
)
FORMATS = (*FORMATS, KALIBR, MATLAB)

UNITS_MM = {"mm": 1.0, "millimeters": 1.0, "millimetres": 1.0, "cm": 10.0, "centimeters": 10.0, "m": 1000.0,
            "meters": 1000.0, "metres": 1000.0, "in": 25.4, "inches": 25.4}  # fmt: skip


def detected(values: dict[str, Any]) -> CalibrationFormat:
    """The format whose marks a file's fields hold (GENERIC where none's do); ValueError naming
    them where several's do."""
    matching = [f for f in FORMATS if all(mark in values for mark in f.marks)]
    if len(matching) > 1:
        raise ValueError(
            f"holds the fields of {' and '.join(f.name for f in matching)}; name the fields in the options"
        )
    return matching[0] if matching else GENERIC


def slrig_devices(values: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """slrig's own calibration.yaml: its devices' maps by name (none for another format's file;
    its calibration.json is read by rig.calibrate.files.load_calibration)."""
    return {
        name: value
        for name, value in values.items()
        if isinstance(value, dict) and value.get("kind") in ("camera", "projector") and "camera_matrix" in value
    }
