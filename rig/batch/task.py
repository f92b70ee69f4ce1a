"""One input reprocessed, as a worker runs it: the frames read from the shared path (never shipped
through the scheduler), the output written under its final name only when complete (the same
atomic rules as the daemon's scans), and an output already made from the same input skipped."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from rig.batch.archive import DIGEST_KEY, ArchiveInput, input_digest, output_digest
from rig.calibrate.foreign import ForeignCalibrationOptions
from rig.config import load_config
from rig.errors import StoreError
from rig.pipeline.scan import ScanResult
from rig.service.reconstruct import reconstruct_folder
from rig.service.tasks import reprocess_to_directory
from rig.store.scandir import DESCRIPTION_NAME, new_scan_id


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
    if item.kind == "scan":
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
