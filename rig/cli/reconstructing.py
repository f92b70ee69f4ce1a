"""`slrig reconstruct`: a scan directory from frames on disk: a scan's own kept frames, decoded
again, or frames another system captured."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rig.cli.calibration_files import OPTIONS, calibration_options
from rig.cli.common import progress_bar
from rig.config import load_config
from rig.errors import UsageError
from rig.pipeline import ScanResult
from rig.service import reconstruct_folder, reprocess_to_directory
from rig.store import DESCRIPTION_NAME, new_scan_id


def cmd_reconstruct(args: argparse.Namespace) -> int:
    scan_id = new_scan_id()
    if (args.frames_dir / "manifest.json").is_file():
        path, result = _reprocess_scan(args, scan_id)
    else:
        path, result = _reconstruct_foreign(args, scan_id)
    pair = result.pairs[0]
    summary = {
        "scan_id": scan_id,
        "path": str(path),
        "points": len(result.cloud),
        "frames": result.frames_projected,
        "decoded": pair.correspondence.counts.get("decoded"),
        "lit": pair.correspondence.counts.get("lit"),
        "warnings": result.warnings,
    }
    for warning in result.warnings:
        print(f"slrig: warning: {warning}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(f"reconstruction {scan_id}: {len(result.cloud)} points from {result.frames_projected} frames")
        print(f"  -> {path}/cloud.ply")
    return 0


def _reprocess_scan(args: argparse.Namespace, scan_id: str) -> tuple[Path, ScanResult]:
    """A scan directory that kept its frames, decoded again with its own codec, rig and calibration
    (or --calibration), written beside it."""
    source = args.frames_dir
    named = ("patterns", *OPTIONS, "calibration_fields")
    refused = [f"--{n.replace('_', '-')}" for n in named if getattr(args, n, None) is not None]
    if refused:
        raise UsageError(f"{', '.join(refused)}: a scan directory's manifest says what its frames are")
    if args.calibration is not None and len(args.calibration) > 1:
        raise UsageError("--calibration: a scan directory is reprocessed with one slrig calibration (a folder)")
    target = _target(args.out, source.parent / scan_id)
    calibration = None if args.calibration is None else args.calibration[0]
    origin = {"reprocessed_from": source.name, "calibration": None if calibration is None else str(calibration)}
    bar = progress_bar(args)
    return reprocess_to_directory(source, target, scan_id, calibration, origin=origin, progress=bar)


def _reconstruct_foreign(args: argparse.Namespace, scan_id: str) -> tuple[Path, ScanResult]:
    """Another system's frames, described by --patterns (or the folder's patterns.yaml)."""
    config = load_config(args.config)
    options = calibration_options(args)
    patterns = args.patterns
    if patterns is None and (args.frames_dir / DESCRIPTION_NAME).is_file():
        patterns = args.frames_dir / DESCRIPTION_NAME
    missing = [flag for flag, value in (("--patterns", patterns), ("--calibration", args.calibration)) if value is None]
    if missing:
        raise UsageError(
            f"{' and '.join(missing)}: {args.frames_dir} is not a scan directory (no manifest.json), so its frames "
            f"need a pattern description (--patterns, or {DESCRIPTION_NAME} in the folder) and a calibration"
        )
    target = _target(args.out, config.output.data_dir / "scans" / scan_id)
    calibration = args.calibration[0] if len(args.calibration) == 1 else list(args.calibration)
    return reconstruct_folder(args.frames_dir, patterns, calibration, target, scan_id, config, options)


def _target(out: Path | None, default: Path) -> Path:
    target = out if out is not None else default
    if target.exists():
        raise UsageError(f"--out: {target} already exists; choose a new directory")
    return target
