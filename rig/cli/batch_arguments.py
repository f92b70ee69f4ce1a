"""The `slrig batch` commands' arguments (rig.cli.arguments builds the whole parser)."""

from __future__ import annotations

import argparse
from pathlib import Path


def _cluster(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "inputs", type=Path, nargs="+", help="scan directories or frames folders, or folders of them (scans/)"
    )
    p.add_argument(
        "--scheduler",
        default="local",
        help="local (a cluster of processes on this machine, the default) or a running scheduler, tcp://HOST:8786",
    )
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core)")
    p.add_argument("--json", action="store_true", help="one JSON object per line: each scan, then the summary")


def _calibration(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--calibration", type=Path, nargs="+", default=None, help=what)


def batch_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    batch = sub.add_parser("batch", help="whole archives on a Dask cluster (pip install -e '.[dask]')")
    action = batch.add_subparsers(dest="action", required=True)
    reprocess = action.add_parser(
        "reprocess",
        help="every scan with kept frames (or frames folder with patterns.yaml) reprocessed, one task each",
    )
    _cluster(reprocess)
    reprocess.add_argument("--out", type=Path, required=True, help="where each input's new scan directory goes")
    _calibration(
        reprocess,
        "a slrig calibration folder for every scan instead of its own; what a frames folder needs "
        "(another tool's files too)",
    )
    evaluate = action.add_parser(
        "eval", help="every simulated scan with kept frames reconstructed again and measured against its truth"
    )
    _cluster(evaluate)
    _calibration(evaluate, "a slrig calibration folder for every scan instead of its own")
    describe = action.add_parser(
        "describe", help="every scan described (recognition) and added to the gallery; scans it holds are skipped"
    )
    _cluster(describe)
    describe.add_argument("--gallery", type=Path, required=True, help="the gallery file (created if absent)")
    describe.add_argument("--label", default=None, help="one label for every scan")
    describe.add_argument(
        "--label-from",
        default=None,
        choices=("parent", "name"),
        help="each scan's label: the folder it lies in (archive/alice/scan-1: alice) or its own name",
    )
