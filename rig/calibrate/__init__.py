"""Calibration: boards, views (placed by the rig where it can, or read from a folder), OpenCV
solvers, quality report, calibration files, and the projector response."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "CalibrationOutcome": "session",
    "ForeignCalibration": "foreign",
    "ForeignCalibrationOptions": "foreign",
    "JSON_NAME": "files",
    "RESPONSE_NAME": "response",
    "calibrate": "session",
    "calibrate_described": "session",
    "calibrate_response": "response",
    "calibration_overrides": "overrides",
    "calibration_world": "files",
    "check_resolution": "foreign",
    "load_calibration": "files",
    "load_response_luts": "response",
    "own_calibration": "foreign",
    "own_calibration_json": "foreign",
    "read_foreign_calibration": "foreign",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "JSON_NAME",
    "RESPONSE_NAME",
    "CalibrationOutcome",
    "ForeignCalibration",
    "ForeignCalibrationOptions",
    "calibrate",
    "calibrate_described",
    "calibrate_response",
    "calibration_overrides",
    "calibration_world",
    "check_resolution",
    "load_calibration",
    "load_response_luts",
    "own_calibration",
    "own_calibration_json",
    "read_foreign_calibration",
]
