"""`slrig batch reprocess`: an archive reprocessed on a Dask cluster (rig.batch)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.batch import connect, find_inputs, reprocess_archive, require_dask
from rig.cli import EXIT_FAILED
from rig.cli.common import progress_bar


def cmd_batch(args: argparse.Namespace) -> int:
    require_dask()  # before the archive is read: say how to get it first
    inputs = find_inputs(args.inputs)
    calibration = list(args.calibration or [])
    bar = progress_bar(args)
    with connect(args.scheduler, args.workers) as cluster:
        where = f"; dashboard {cluster.dashboard}" if cluster.dashboard else ""
        memory = "" if cluster.worker_memory else " (the workers offer no MEMORY resource: scans are not sized)"
        print(f"slrig batch: {len(inputs)} inputs on {cluster.workers} workers{where}{memory}", file=sys.stderr)
        summary = reprocess_archive(cluster, inputs, args.out, calibration, _printer(args), bar)
    counts = {name: len(items) for name, items in summary.as_dict().items()}
    if args.json:
        print(json.dumps({"event": "summary", **counts, "failed_inputs": summary.failed}, allow_nan=False))
    else:
        print(f"{counts['done']} done, {counts['skipped']} skipped (already made from the same input), "
              f"{counts['failed']} failed")  # fmt: skip
    return EXIT_FAILED if summary.failed else 0


def _printer(args: argparse.Namespace) -> Any:
    def show(event: dict[str, Any]) -> None:
        if args.json:
            print(json.dumps(event, allow_nan=False), flush=True)
        elif event["event"] == "failed":
            print(f"failed  {event['name']}: {event['error']}", flush=True)
        elif event["event"] == "done":
            made = f"{event['points']} points in {event['seconds']} s"
            print(f"done    {event['name']}: {made} -> {event['path']}", flush=True)
        else:
            print(f"skipped {event['name']}: {event['path']} was made from the same input", flush=True)

    return show
