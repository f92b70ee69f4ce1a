"""What one scan or reprocessing does, from an open rig (or stored frames) to its
stored result. The CLI runs these directly; the job service runs them in its worker."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rig.assembly import open_rig
from rig.config import RigConfig, config_from_dict
from rig.evaluate import measure_on_bench
from rig.opened_rig import Rig
from rig.pipeline import ScanResult, reconstruct_exposures, reconstruct_frames, scan_with_exposure
from rig.plan import RingPlan
from rig.progress import ProgressCallback, ProgressTracker
from rig.service.adaptive import adaptive_scan, plan_check
from rig.service.imports import reconstruction_inputs
from rig.service.reconstruct import reconstruct_folder
from rig.service.space import check_free_space, expected_scan_bytes
from rig.store import read_mask_skews, read_scan_frames, write_scan


def scan_to_directory(
    the_rig: Rig,
    target: Path,
    scan_id: str,
    codec: str | None = None,
    keep_frames: bool = False,
    progress: ProgressCallback | None = None,
) -> tuple[Path, ScanResult]:
    """Scan, measure against ground truth where the rig has it, and write the scan directory."""
    result = scan_with_exposure(the_rig, codec, progress=progress, keep_frames=keep_frames)
    tracker = ProgressTracker(progress)
    tracker.report("store", 0.95)
    metrics, errors = measure_on_bench(the_rig, result)
    path = write_scan(the_rig, result, target, scan_id, metrics, errors=errors)
    tracker.report("done", 1.0)
    return path, result


def scan_job_to_directory(
    the_rig: Rig, target: Path, scan_id: str, request: dict[str, Any], progress: ProgressCallback | None = None
) -> tuple[Path, ScanResult]:
    """A scan as the REST API asks for it (rig.api.models.ScanRequest): plain, adaptive, or a plan's rings."""
    keep_frames = bool(request.get("keep_frames"))
    the_rig = with_requested_exposure(the_rig, request)
    if request.get("adaptive") or request.get("plan"):
        plan = RingPlan.from_dict(request["plan"]) if request.get("plan") else None
        path, result, _ = adaptive_scan_to_directory(
            the_rig, target, scan_id, request.get("tolerance_mm"), plan, keep_frames, progress,
            request.get("tolerance_quantile"),
        )  # fmt: skip
        return path, result
    return scan_to_directory(the_rig, target, scan_id, request.get("codec"), keep_frames, progress)


def with_requested_exposure(the_rig: Rig, request: dict[str, Any]) -> Rig:
    """The rig scanning at the request's `exposure`, `hdr` and `adaptive_projection` (scan.exposure),
    where it gives them."""
    asked = {k: request[k] for k in ("exposure", "hdr", "adaptive_projection") if request.get(k) is not None}
    if not asked:
        return the_rig
    data = the_rig.config.model_dump(mode="json")
    data["scan"]["exposure"].update(asked)
    return dataclasses.replace(the_rig, config=config_from_dict(data, "request"))


def adaptive_scan_to_directory(
    the_rig: Rig,
    target: Path,
    scan_id: str,
    tolerance_mm: float | None = None,
    plan: RingPlan | None = None,
    keep_frames: bool = False,
    progress: ProgressCallback | None = None,
    quantile: float | None = None,
) -> tuple[Path, ScanResult, RingPlan]:
    """An adaptive scan (rig.service.adaptive) written like any scan, its plan in the manifest."""
    result, plan, sparse = adaptive_scan(the_rig, tolerance_mm, plan, keep_frames, progress, quantile)
    tracker = ProgressTracker(progress)
    tracker.report("store", 0.95)
    metrics, errors = measure_on_bench(sparse, result)
    assert result.adaptive is not None
    result.adaptive["check"] = plan_check(result.adaptive, metrics)  # the promise beside what was measured
    path = write_scan(sparse, result, target, scan_id, metrics, errors=errors)
    tracker.report("done", 1.0)
    return path, result, plan


def reprocess_to_directory(
    source: Path,
    target: Path,
    scan_id: str,
    calibration: Path | None = None,
    overrides: dict[str, Any] | None = None,
    origin: dict[str, Any] | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[Path, ScanResult]:
    """Decode and triangulate a stored scan's frames again (no devices), with another calibration
    folder and `overrides` of its scan section, and write a new scan directory."""
    tracker = ProgressTracker(progress)
    with reprocessed(source, calibration, overrides, tracker, target.parent) as (geometry, result):
        tracker.report("store", 0.95)
        metrics, errors = measure_on_bench(geometry, result)
        path = write_scan(geometry, result, target, scan_id, metrics, origin, errors)
    return path, result


def reprocess_job(
    source: Path,
    target: Path,
    scan_id: str,
    calibration: Path | None,
    overrides: dict[str, Any],
    origin: dict[str, Any],
    progress: ProgressCallback | None = None,
) -> dict[str, Any]:
    """A reprocessing job's work, on the daemon's worker or a cluster's (rig.service.remote): the
    new scan directory written, and its summary."""
    path, result = reprocess_to_directory(source, target, scan_id, calibration, overrides, origin, progress)
    return scan_summary(path, result)


@contextmanager
def reprocessed(
    source: Path,
    calibration: Path | None = None,
    overrides: dict[str, Any] | None = None,
    tracker: ProgressTracker | None = None,
    writes_to: Path | None = None,
) -> Iterator[tuple[Rig, ScanResult]]:
    """A stored scan's frames decoded and triangulated again, on a rig of its geometry only (open
    while the caller uses it: its ground truth, for a simulated scan); `writes_to`: where the result
    will be stored, whose free space is checked first."""
    tracker = tracker or ProgressTracker(None)
    manifest, frames = read_scan_frames(source)
    data = manifest["config"]
    if calibration is not None:
        data["calibration"]["file"] = str(calibration)
    data["scan"].update(overrides or {})
    config = config_from_dict(data, f"scan {manifest['scan_id']}")
    if writes_to is not None:
        check_free_space(writes_to, expected_scan_bytes(config, {}), "this reprocessing")
    tracker.report("decode", 0.6)
    passes = len(next(iter((manifest.get("exposure") or {}).get("exposures_us", {}).values()), []))
    skews = read_mask_skews(source, manifest)
    with open_rig(config, with_devices=False) as geometry:
        if passes > 1 or skews:  # an HDR scan's passes merged again, an adaptive one's masks' lean taken off
            result = reconstruct_exposures(geometry, manifest["codec"]["name"], frames, max(passes, 1), tracker, skews)
            result.exposure = manifest["exposure"]
        else:
            result = reconstruct_frames(geometry, manifest["codec"]["name"], frames, tracker)
        yield geometry, result


def reconstruction_to_directory(
    data_dir: Path,
    calibration_folder: Callable[[str], Path],
    request: dict[str, Any],
    target: Path,
    scan_id: str,
    config: RigConfig,
    progress: ProgressCallback | None = None,
) -> dict[str, Any]:
    """A reconstruction request (frames uploaded under data_dir's imports) written as a scan."""
    frames, patterns, calibration, options = reconstruction_inputs(data_dir, calibration_folder, request)
    path, result = reconstruct_folder(frames, patterns, calibration, target, scan_id, config, options, progress)
    return scan_summary(path, result)


def scan_summary(path: Path, result: ScanResult) -> dict[str, Any]:
    """What a finished scan job reports: counts, timings, and the files it wrote."""
    manifest = json.loads((path / "manifest.json").read_text())
    metrics = manifest.get("metrics") or {}
    cloud = metrics.get("merged") or (next(iter(metrics.values())) if len(metrics) == 1 else None)
    return {
        "points": len(result.cloud),
        "frames_projected": result.frames_projected,
        "timings_ms": {k: round(v, 1) for k, v in result.timings_ms.items()},
        "files": sorted(p.name for p in path.iterdir() if p.is_file()),
        "codec": manifest.get("codec", {}).get("name") if isinstance(manifest.get("codec"), dict) else None,
        "economy": manifest.get("economy"),
        "exposure": _exposure_summary(manifest.get("exposure")),
        # against the simulator's ground truth (none on a real bench): the cloud's, as the manifest's metrics
        "metrics": None if not isinstance(cloud, dict) else {k: cloud.get(k) for k in _SUMMARY_METRICS if k in cloud},
    }


_SUMMARY_METRICS = ("rms_mm", "p95_mm", "completeness", "points")


def _exposure_summary(record: Any) -> dict[str, Any] | None:
    """A scan's exposure record without its looks (the pre-captures' histograms: the manifest has them)."""
    if not isinstance(record, dict):
        return None
    return {k: v for k, v in record.items() if k in ("mode", "exposures_us")}
