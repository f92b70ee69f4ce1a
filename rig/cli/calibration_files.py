"""`slrig calibration show FILE...`: what slrig reads from any calibration file, to check it before
scanning with it: the format it told by the fields, the devices, their resolutions, intrinsics,
distortion and poses, which way the file's R, T map and in what unit, and every field's name."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from pydantic import ValidationError

from rig.calibrate import ForeignCalibration, ForeignCalibrationOptions, read_foreign_calibration
from rig.config import validation_problems
from rig.errors import CalibrationError
from rig.geometry import CameraModel

OPTIONS = (
    "camera",
    "projector",
    "extrinsics",
    "world",
    "translation_scale",
    "camera_resolution",
    "projector_resolution",
    "ignore_projector_distortion",
)


def calibration_options(args: argparse.Namespace) -> ForeignCalibrationOptions:
    """The import options the command line gives (CalibrationError naming the flag at fault)."""
    given: dict[str, Any] = {name: getattr(args, name) for name in OPTIONS if getattr(args, name, None) is not None}
    fields = getattr(args, "calibration_fields", None)
    if fields:
        given["keys"] = parse_fields(fields)
    try:
        return ForeignCalibrationOptions(**given)
    except ValidationError as exc:
        raise CalibrationError(
            "calibration options: " + "; ".join(_as_flag(line) for line in validation_problems(exc))
        ) from None


def parse_fields(text: str) -> dict[str, str]:
    """`camera_matrix=Kc,rotation=Rp` as {field: the file's name}, names kept as written."""
    pairs = [part.split("=", 1) for part in text.split(",") if part.strip()]
    if any(len(pair) != 2 or not pair[0].strip() or not pair[1].strip() for pair in pairs):
        raise CalibrationError(f"--calibration-fields: {text!r} is not FIELD=NAME,FIELD=NAME,...")
    return {field.strip(): name.strip() for field, name in pairs}


def _as_flag(problem: str) -> str:
    """'camera_resolution: ...' as '--camera-resolution: ...'."""
    field, _, reason = problem.partition(":")
    return f"--{field.replace('_', '-')}:{reason}"


def cmd_calibration(args: argparse.Namespace) -> int:
    options = calibration_options(args)
    found = read_foreign_calibration(list(args.files), options, single_device=True)
    shown = described(found, options)
    shown["files"] = [str(f) for f in args.files]
    if args.json:
        print(json.dumps(shown, allow_nan=False))
        return 0
    files = ", ".join(shown["files"])
    pose = f"R, T read as {shown['extrinsics']}, " if shown["extrinsics"] else ""
    print(f"{files}: {shown['format']}; {pose}its lengths in {shown['unit']} (shown in mm); world: {shown['world']}")
    for name, device in shown["devices"].items():
        k = device["K"]
        print(
            f"  {device['kind']} {name}: {device['resolution'][0]}x{device['resolution'][1]}, fx {k[0][0]:.6g} "
            f"fy {k[1][1]:.6g} cx {k[0][2]:.6g} cy {k[1][2]:.6g}, distortion {_numbers(device['dist'])}"
        )
        print(f"    centre {_numbers(device['center_mm'])} mm, rotation {device['rotation_deg']:.4g} deg (world frame)")
    rms = "not in the file" if shown["rms_px"] is None else f"{shown['rms_px']:.4g} px"
    if shown["baseline_mm"] is None:
        print(f"  a camera alone: no projector, no baseline; rms {rms}")
    else:
        print(f"  baseline {shown['baseline_mm']:.6g} mm; rms {rms}")
    print("  fields read: " + ", ".join(f"{field} <- {name}" for field, name in shown["found"].items()))
    return 0


def described(found: ForeignCalibration, options: ForeignCalibrationOptions) -> dict[str, Any]:
    """What `calibration show --json` prints of a read calibration."""
    devices = {options.camera: _device("camera", found.camera)}
    baseline = None
    if found.projector is not None:
        devices[options.projector] = _device("projector", found.projector)
        baseline = round(float(np.linalg.norm(found.projector.center - found.camera.center)), 6)
    return {
        "format": found.format,
        "extrinsics": found.extrinsics,
        "unit": found.unit,
        "world": found.world if found.format != "slrig" or found.world != "board" else "board (its first view's)",
        "rms_px": found.rms_px,
        "baseline_mm": baseline,
        "found": found.found,
        "devices": devices,
    }


def _device(kind: str, model: CameraModel) -> dict[str, Any]:
    angle = float(np.degrees(np.arccos(np.clip((np.trace(model.R) - 1.0) / 2.0, -1.0, 1.0))))
    return {
        "kind": kind,
        "resolution": [model.width, model.height],
        "K": np.asarray(model.K).round(6).tolist(),
        "dist": np.asarray(model.dist).ravel().round(9).tolist(),
        "R": np.asarray(model.R).round(9).tolist(),
        "t": np.asarray(model.t).round(6).tolist(),
        "center_mm": np.asarray(model.center).round(6).tolist(),
        "rotation_deg": round(angle, 6),
    }


def _numbers(values: list[float]) -> str:
    return "[" + " ".join(f"{v:.4g}" for v in values) + "]"
