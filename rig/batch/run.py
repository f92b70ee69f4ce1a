"""An archive reprocessed on a cluster: one task per input, each asking for the memory its scan
needs; a failed input is reported with its error and the others go on; a worker that dies takes
no scan with it (the scheduler gives its scan to another worker, up to Dask's allowed failures);
the summary lists what was done, skipped (already made from the same input) and failed."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig.assembly import CAMERA_BYTES_PER_PIXEL, scan_memory
from rig.batch.archive import ArchiveInput
from rig.batch.cluster import MEMORY, Cluster
from rig.batch.tasks import reprocess_one
from rig.config import config_from_dict
from rig.errors import SlrigError
from rig.progress import ProgressCallback, ProgressTracker
from rig.store import read_image_header

EventCallback = Callable[[dict[str, Any]], None]


@dataclass
class BatchSummary:
    done: list[dict[str, Any]] = field(default_factory=list)
    skipped: list[dict[str, Any]] = field(default_factory=list)
    failed: list[dict[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"done": self.done, "skipped": self.skipped, "failed": self.failed}


def memory_needed(item: ArchiveInput) -> int:
    """Bytes reprocessing `item` holds, from the memory model (a scan's config) or from its frames'
    size (a frames folder), beside a worker's fixed overhead."""
    if item.layout == "scan":
        manifest = json.loads((item.path / "manifest.json").read_text())
        return sum(scan_memory(config_from_dict(manifest["config"], f"scan {item.name}")).values())
    frames = sorted(p for p in item.path.iterdir() if p.suffix.lower() in (".png", ".tif", ".tiff", ".bmp", ".jpg"))
    if not frames:
        return 0
    header = read_image_header(frames[0])
    sample_bytes = header.channels * (2 if header.bits_per_sample > 8 else 1)
    return header.pixels * (len(frames) * sample_bytes + CAMERA_BYTES_PER_PIXEL)


def reprocess_archive(
    cluster: Cluster,
    inputs: list[ArchiveInput],
    out: Path,
    calibration: list[Path],
    on_event: EventCallback | None = None,
    progress: ProgressCallback | None = None,
) -> BatchSummary:
    """Every input reprocessed into out/<its name> on `cluster` (see the module docstring)."""
    return run_archive(cluster, inputs, Work("reprocess", reprocess_one, (out, calibration)), on_event, progress)


@dataclass(frozen=True)
class Work:
    """What each input's task is: `task(item, *args)` returning a summary with "status" done or
    skipped; `received`, where given, turns each done summary into the one recorded (on the client:
    a descriptor added to the gallery, and left out of the summary)."""

    stage: str
    task: Callable[..., dict[str, Any]]
    args: tuple[Any, ...]
    received: Callable[[dict[str, Any]], dict[str, Any]] | None = None


def run_archive(
    cluster: Cluster,
    inputs: list[ArchiveInput],
    work: Work,
    on_event: EventCallback | None = None,
    progress: ProgressCallback | None = None,
) -> BatchSummary:
    """`work` on every input, one task each, sized by the memory its scan needs (see the module
    docstring); each outcome reported to `on_event` as it comes."""
    summary = BatchSummary()
    tracker = ProgressTracker(progress)
    largest = max(cluster.worker_memory, default=None)
    futures = {}
    for item in inputs:
        try:
            needed = memory_needed(item)
        except Exception as exc:  # an unreadable input fails alone
            _failed(summary, on_event, item, f"{type(exc).__name__}: {exc}")
            continue
        if largest is not None and needed > largest:
            offered = f"the largest worker offers {largest / 1e9:.1f} GB"
            _failed(summary, on_event, item, f"needs {needed / 1e9:.1f} GB, {offered}")
            continue
        resources = {MEMORY: max(1, needed)} if largest is not None else None
        key = f"{work.stage}-{item.name}"
        futures[cluster.client.submit(work.task, item, *work.args, key=key, resources=resources, pure=False)] = item
    from distributed import as_completed  # an optional extra: cluster.connect has checked it is here

    finished = len(summary.failed)
    for future in as_completed(list(futures)):
        item = futures.pop(future)
        finished += 1
        result, error = _outcome(future, work)
        if error is not None:
            _failed(summary, on_event, item, error)
        else:
            (summary.done if result["status"] == "done" else summary.skipped).append(result)
            if on_event is not None:
                on_event({"event": result["status"], **result})
        future.release()
        tracker.report(work.stage, finished / max(1, len(inputs)), item.name)
    return summary


def _outcome(future: Any, work: Work) -> tuple[dict[str, Any], str | None]:
    """A finished task's summary (as `work.received` makes it), or why it failed."""
    if future.status != "finished":
        return {}, _reason(future.exception())
    result = future.result()
    if work.received is None or result["status"] != "done":
        return result, None
    try:
        return work.received(result), None
    except SlrigError as exc:  # what the client did with it was refused (a gallery's settings)
        return {}, f"{type(exc).__name__}: {exc}"


def _failed(summary: BatchSummary, on_event: EventCallback | None, item: ArchiveInput, error: str) -> None:
    record = {"name": item.name, "status": "failed", "path": str(item.path), "error": error}
    summary.failed.append(record)
    if on_event is not None:
        on_event({"event": "failed", **record})


def _reason(exc: BaseException | None) -> str:
    name = type(exc).__name__
    if name == "KilledWorker":
        return "its worker died on it every time it was tried (out of memory, or killed)"
    return f"{name}: {exc}"
