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
    """slrig's own calibration.yaml: its devices' maps by name (none for another format's file)."""
    return {
        name: value
        for name, value in values.items()
        if isinstance(value, dict) and value.get("kind") in ("camera", "projector") and "camera_matrix" in value
    }
