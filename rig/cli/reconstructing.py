"""`slrig reconstruct`: a scan directory from frames another system captured."""

from __future__ import annotations

import argparse
import json

from pydantic import ValidationError

from rig.calibrate.foreign import ForeignCalibrationOptions
from rig.config import load_config
from rig.config.problems import problems
from rig.errors import CalibrationError, UsageError
from rig.service.reconstruct import reconstruct_folder
from rig.store.scandir import new_scan_id

OPTIONS = (
    "camera",
    "projector",
    "extrinsics",
    "world",
    "translation_scale",
    "camera_resolution",
    "projector_resolution",
)


def cmd_reconstruct(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    given = {name: getattr(args, name) for name in OPTIONS if getattr(args, name) is not None}
    try:
        options = ForeignCalibrationOptions(**given)
    except ValidationError as exc:
        lines = [_as_flag(line) for line in problems(exc)]
        raise CalibrationError("calibration options: " + "; ".join(lines)) from None
    scan_id = new_scan_id()
    target = args.out if args.out is not None else config.output.data_dir / "scans" / scan_id
    if target.exists():
        raise UsageError(f"--out: {target} already exists; choose a new directory")
    path, result = reconstruct_folder(
        args.frames_dir, args.patterns, args.calibration, target, scan_id, config, options
    )
    pair = result.pairs[0]
    summary = {
        "scan_id": scan_id,
        "path": str(path),
        "points": len(result.cloud),
        "frames": result.frames_projected,
        "decoded": pair.correspondence.counts.get("decoded"),
        "lit": pair.correspondence.counts.get("lit"),
    }
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(f"reconstruction {scan_id}: {len(result.cloud)} points from {result.frames_projected} frames")
        print(f"  -> {path}/cloud.ply")
    return 0


def _as_flag(problem: str) -> str:
    """'camera_resolution: ...' as '--camera-resolution: ...'."""
    field, _, reason = problem.partition(":")
    return f"--{field.replace('_', '-')}:{reason}"
