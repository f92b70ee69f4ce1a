"""How fast the command line starts: `slrig --help` and `slrig devices --help` against the time
Python takes to import what any slrig command needs (numpy, yaml, pydantic), medians of repeated
runs in fresh processes. Prints one JSON object; with --docs rewrites the startup block of
docs/results.md.

    python bench/cli_startup.py [--docs] [--runs 15]
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

RUNS = 15
COMMANDS = {
    "python -c 'import numpy, yaml, pydantic'": [sys.executable, "-c", "import numpy, yaml, pydantic"],
    "slrig --help": [sys.executable, "-m", "rig.cli", "--help"],
    "slrig scan --help": [sys.executable, "-m", "rig.cli", "scan", "--help"],
}


def _median_s(command: list[str]) -> float:
    times = []
    for _ in range(RUNS):
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, timeout=120)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure() -> dict[str, Any]:
    _median_s(COMMANDS["slrig --help"])  # file caches warm, as on a second call
    seconds = {name: round(_median_s(command), 4) for name, command in COMMANDS.items()}
    floor = seconds["python -c 'import numpy, yaml, pydantic'"]
    return {
        "benchmark": "cli_startup",
        "runs": RUNS,
        "seconds": seconds,
        "times_the_imports": {k: round(v / floor, 2) for k, v in seconds.items()},
    }


def table(m: dict[str, Any]) -> str:
    rows = [
        [f"`{name}`", f"{1000 * s:.0f} ms", f"{m['times_the_imports'][name]:.2f}x"] for name, s in m["seconds"].items()
    ]
    return markdown_table(["command", "median", "against the imports"], rows) + f"\n\nMedians of {m['runs']} runs each."


def main() -> None:
    run(__doc__ or "", "cli-startup", measure, table)


if __name__ == "__main__":
    main()
