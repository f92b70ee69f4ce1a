"""The `slrig batch` commands' arguments (rig.cli.arguments builds the whole parser)."""

from __future__ import annotations

import argparse
from pathlib import Path


def batch_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    batch = sub.add_parser("batch", help="reprocess whole archives on a Dask cluster (pip install -e '.[dask]')")
    action = batch.add_subparsers(dest="action", required=True)
    reprocess = action.add_parser(
        "reprocess",
        help="every scan with kept frames (or frames folder with patterns.yaml) reprocessed, one task each",
    )
    reprocess.add_argument(
        "inputs", type=Path, nargs="+", help="scan directories or frames folders, or folders of them (scans/)"
    )
    reprocess.add_argument("--out", type=Path, required=True, help="where each input's new scan directory goes")
    reprocess.add_argument(
        "--scheduler",
        default="local",
        help="local (a cluster of processes on this machine, the default) or a running scheduler, tcp://HOST:8786",
    )
    reprocess.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per core)")
    reprocess.add_argument(
        "--calibration",
        type=Path,
        nargs="+",
        default=None,
        help="a slrig calibration folder for every scan instead of its own; what a frames folder needs "
        "(another tool's files too)",
    )
    reprocess.add_argument("--json", action="store_true", help="one JSON object per line: each scan, then the summary")
