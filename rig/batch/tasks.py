"""What a worker does with one input, reading it from the shared path (frames are never shipped
through the scheduler): reprocess it into an output directory (written under its final name only
when complete, the same atomic rules as the daemon's scans; an output already made from the same
input skipped), measure it again against the simulated bench's truth, or describe it for the
recognition gallery."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from rig.batch.archive import DIGEST_KEY, ArchiveInput, input_digest, output_digest
from rig.calibrate import ForeignCalibrationOptions
from rig.config import load_config
from rig.errors import StoreError
from rig.evaluate import measure_on_bench
from rig.pipeline import ScanResult
from rig.recognition import DescriptorSettings
from rig.service import describe_scan, reconstruct_folder, reprocess_to_directory, reprocessed
from rig.store import DESCRIPTION_NAME, new_scan_id


def reprocess_one(item: ArchiveInput, out: Path, calibration: list[Path]) -> dict[str, Any]:
    """Reprocess `item` into out/<its name>; a summary with "status" done or skipped. Raises (a
    SlrigError naming the input for bad input) when it cannot; nothing is left under the name."""
    start = time.monotonic()
    target = out / item.name
    digest = input_digest(item, calibration)
    if target.exists():
        made_from = output_digest(target)
        if made_from == digest:
            return {"name": item.name, "status": "skipped", "path": str(target)}
        raise StoreError(
            f"{target} exists and was not made from this input "
            f"({'another input or calibration' if made_from else 'not by slrig batch'}): not overwritten; "
            "remove it or choose another --out"
        )
    scan_id = new_scan_id()
    if item.layout == "scan":
        result = _stored_scan(item, target, scan_id, calibration, digest)
    else:
        result = _frames_folder(item, target, scan_id, calibration, digest)
    return {
        "name": item.name,
        "status": "done",
        "path": str(target),
        "scan_id": scan_id,
        "points": len(result.cloud),
        "seconds": round(time.monotonic() - start, 3),
    }


def _stored_scan(item: ArchiveInput, target: Path, scan_id: str, calibration: list[Path], digest: str) -> ScanResult:
    if len(calibration) > 1:
        raise StoreError(f"{item.path}: a scan directory is reprocessed with one slrig calibration (a folder)")
    folder = calibration[0] if calibration else None
    origin = {"reprocessed_from": item.name, "calibration": None if folder is None else str(folder), DIGEST_KEY: digest}
    return reprocess_to_directory(item.path, target, scan_id, folder, origin=origin)[1]


def _frames_folder(item: ArchiveInput, target: Path, scan_id: str, calibration: list[Path], digest: str) -> ScanResult:
    if not calibration:
        raise StoreError(f"{item.path}: a frames folder needs --calibration (its frames carry no rig)")
    where = calibration[0] if len(calibration) == 1 else calibration
    patterns = item.path / DESCRIPTION_NAME
    config, options, origin = load_config(None), ForeignCalibrationOptions(), {DIGEST_KEY: digest}
    return reconstruct_folder(item.path, patterns, where, target, scan_id, config, options, origin=origin)[1]


def evaluate_one(item: ArchiveInput, calibration: list[Path]) -> dict[str, Any]:
    """A simulated scan's frames reconstructed again (with `calibration`, else its own) and measured
    against the truth of the bench its manifest describes; nothing is written."""
    if item.layout != "scan":
        raise StoreError(f"{item.path}: a frames folder has no simulated bench to measure against")
    if len(calibration) > 1:
        raise StoreError(f"{item.path}: a scan directory is reprocessed with one slrig calibration (a folder)")
    start = time.monotonic()
    if json.loads((item.path / "manifest.json").read_text())["config"].get("simulation") is None:  # before decoding
        raise StoreError(f"{item.path}: not a scan of the simulated bench (no ground truth to measure against)")
    with reprocessed(item.path, calibration[0] if calibration else None) as (geometry, result):
        metrics, _ = measure_on_bench(geometry, result)
    return {
        "name": item.name,
        "status": "done",
        "codec": result.codec,
        "points": len(result.cloud),
        "metrics": metrics,
        "seconds": round(time.monotonic() - start, 3),
    }


def describe_one(item: ArchiveInput, settings: DescriptorSettings) -> dict[str, Any]:
    """A scan's recognition descriptor (rig.service.recognition.describe_scan), for the client to add."""
    if item.layout != "scan":
        raise StoreError(f"{item.path}: a frames folder has no surface to describe (reprocess it first)")
    scan_id, descriptor = describe_scan(item.path, settings)
    return {"name": item.name, "status": "done", "scan_id": scan_id, "descriptor": descriptor}
