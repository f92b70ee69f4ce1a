"""An archive described for the recognition gallery, and measured again against the simulated
bench's truth, on a cluster: the work of `slrig batch describe` and `slrig batch eval`.

Describing runs on the workers; adding to the gallery on the client, one entry at a time as each
description arrives (a gallery is one SQLite file, written by one process), so a crash loses no
entry already added and a rerun skips the scans the gallery holds (by scan id) without describing
them again."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rig.batch.archive import ArchiveInput
from rig.batch.cluster import Cluster
from rig.batch.run import BatchSummary, EventCallback, Work, run_archive
from rig.batch.tasks import describe_one, evaluate_one
from rig.errors import UsageError
from rig.progress import ProgressCallback
from rig.recognition import LABEL, DescriptorSettings, Gallery

LABEL_SOURCES = ("parent", "name")


def labeller(label: str | None, label_from: str | None) -> Callable[[ArchiveInput], str]:
    """Each input's label: `label` for all, or its folder's `label_from` ("parent": the folder it
    lies in, as in archive/alice/scan-1; "name": its own)."""
    if (label is None) == (label_from is None):
        raise UsageError("--label NAME (one label for every scan) or --label-from parent|name, one of them")
    if label is not None:
        return lambda item: label
    if label_from not in LABEL_SOURCES:
        raise UsageError(f"--label-from {label_from}: parent (the folder a scan lies in) or name (its own)")
    return (lambda item: item.path.resolve().parent.name) if label_from == "parent" else (lambda item: item.name)


def describe_archive(
    cluster: Cluster,
    inputs: list[ArchiveInput],
    gallery: Gallery,
    label_of: Callable[[ArchiveInput], str],
    settings: DescriptorSettings | None = None,
    on_event: EventCallback | None = None,
    progress: ProgressCallback | None = None,
) -> BatchSummary:
    """Every scan not in `gallery` yet described on the cluster (with the gallery's settings, else
    `settings`) and added under its label."""
    if settings is not None:
        gallery.check_settings(settings)
    chosen = gallery.settings() or settings or DescriptorSettings()
    held = gallery.scan_ids()
    todo, skipped, refused, labels = [], [], [], {}
    for item in inputs:
        scan_id, label = _scan_id(item), label_of(item)
        if scan_id is not None and scan_id in held:
            skipped.append({"name": item.name, "status": "skipped", "scan_id": scan_id, "path": str(item.path)})
        elif not LABEL.fullmatch(label):  # refused before its description is made
            error = f"label {label!r}: not a plain name (letters, digits, '.', '_' or '-', at most 64)"
            refused.append({"name": item.name, "status": "failed", "path": str(item.path), "error": error})
        else:
            todo.append(item)
            labels[item.name] = label

    def added(result: dict[str, Any]) -> dict[str, Any]:
        entry = gallery.add(labels[result["name"]], result["scan_id"], result.pop("descriptor"))
        return {**result, "label": entry.label, "entry_id": entry.id}

    for record in (*skipped, *refused):
        if on_event is not None:
            on_event({"event": record["status"], **record})
    summary = run_archive(cluster, todo, Work("describe", describe_one, (chosen,), added), on_event, progress)
    summary.skipped[:0], summary.failed[:0] = skipped, refused
    return summary


def evaluate_archive(
    cluster: Cluster,
    inputs: list[ArchiveInput],
    calibration: list[Path],
    on_event: EventCallback | None = None,
    progress: ProgressCallback | None = None,
) -> BatchSummary:
    """Every simulated scan reconstructed again and measured against its bench's truth."""
    return run_archive(cluster, inputs, Work("eval", evaluate_one, (calibration,)), on_event, progress)


def accuracy_summary(done: list[dict[str, Any]]) -> dict[str, Any]:
    """Over the scans measured: each scan's figures (its merged cloud's, else its first pair's) and
    their median and worst."""
    rows = []
    for result in done:
        metrics = result["metrics"]
        figures = metrics.get("merged") or next(iter(metrics.values()), {})
        rows.append({"name": result["name"], **{k: figures.get(k) for k in ("rms_mm", "p95_mm", "completeness")}})
    rms = [r["rms_mm"] for r in rows if r["rms_mm"] is not None]
    complete = [r["completeness"] for r in rows if r["completeness"] is not None]
    return {
        "scans": rows,
        "median_rms_mm": float(np.median(rms)) if rms else None,
        "worst_rms_mm": max(rms) if rms else None,
        "median_completeness": float(np.median(complete)) if complete else None,
        "least_completeness": min(complete) if complete else None,
    }


def _scan_id(item: ArchiveInput) -> str | None:
    try:
        return str(json.loads((item.path / "manifest.json").read_text())["scan_id"])
    except (OSError, ValueError, KeyError, TypeError):
        return None  # the task reports what is wrong with it
