"""`slrig batch reprocess | eval | describe`: an archive on a Dask cluster (rig.batch)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.batch import (
    BatchSummary,
    Cluster,
    accuracy_summary,
    connect,
    describe_archive,
    evaluate_archive,
    find_inputs,
    labeller,
    reprocess_archive,
    require_dask,
)
from rig.cli import EXIT_FAILED
from rig.cli.common import progress_bar
from rig.recognition import Gallery


def cmd_batch(args: argparse.Namespace) -> int:
    require_dask()  # before the archive is read: say how to get it first
    label_of = labeller(args.label, args.label_from) if args.action == "describe" else None
    inputs = find_inputs(args.inputs)
    bar = progress_bar(args)
    with connect(args.scheduler, args.workers) as cluster:
        _started(cluster, len(inputs))
        if args.action == "reprocess":
            summary = reprocess_archive(cluster, inputs, args.out, list(args.calibration or []), _printer(args), bar)
        elif args.action == "eval":
            summary = evaluate_archive(cluster, inputs, list(args.calibration or []), _printer(args), bar)
        else:
            assert label_of is not None
            with Gallery(args.gallery, create=True) as gallery:
                summary = describe_archive(cluster, inputs, gallery, label_of, None, _printer(args), bar)
    _summarise(args, summary)
    return EXIT_FAILED if summary.failed else 0


def _started(cluster: Cluster, inputs: int) -> None:
    where = f"; dashboard {cluster.dashboard}" if cluster.dashboard else ""
    memory = "" if cluster.worker_memory else " (the workers offer no MEMORY resource: scans are not sized)"
    print(f"slrig batch: {inputs} inputs on {cluster.workers} workers{where}{memory}", file=sys.stderr)


def _summarise(args: argparse.Namespace, summary: BatchSummary) -> None:
    counts = {name: len(items) for name, items in summary.as_dict().items()}
    accuracy = accuracy_summary(summary.done) if args.action == "eval" else None
    if args.json:
        extra = {"accuracy": accuracy} if accuracy is not None else {}
        print(json.dumps({"event": "summary", **counts, "failed_inputs": summary.failed, **extra}, allow_nan=False))
        return
    if accuracy is not None and accuracy["median_rms_mm"] is not None:
        print(
            f"rms: median {accuracy['median_rms_mm']:.4f} mm, worst {accuracy['worst_rms_mm']:.4f} mm; completeness: "
            f"median {accuracy['median_completeness']:.4f}, least {accuracy['least_completeness']:.4f}"
        )
    kept = "already made from the same input" if args.action == "reprocess" else "already in the gallery"
    skipped = f", {counts['skipped']} skipped ({kept})" if args.action != "eval" else ""
    print(f"{counts['done']} done{skipped}, {counts['failed']} failed")


def _printer(args: argparse.Namespace) -> Any:
    def show(event: dict[str, Any]) -> None:
        if args.json:
            print(json.dumps(event, allow_nan=False), flush=True)
        elif event["event"] == "failed":
            print(f"failed  {event['name']}: {event['error']}", flush=True)
        elif event["event"] == "skipped":
            print(f"skipped {event['name']}", flush=True)
        else:
            print(f"done    {event['name']}: {_done(event)}", flush=True)

    return show


def _done(event: dict[str, Any]) -> str:
    if "entry_id" in event:
        return f"scan {event['scan_id']} added as {event['label']} (entry {event['entry_id']})"
    if "metrics" in event:
        figures = accuracy_summary([event])["scans"][0]
        rms, complete = figures["rms_mm"], figures["completeness"]
        measured = "no points" if rms is None else f"rms {rms:.4f} mm, completeness {complete:.4f}"
        return f"{event['codec']}, {event['points']} points, {measured}"
    return f"{event['points']} points in {event['seconds']} s -> {event['path']}"
