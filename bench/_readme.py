"""Replace a marked block of the manual (README.md or a page of docs/) with a table a benchmark
produced, signed with the command, the date and the machine that produced it. Every benchmark
takes `--docs` for this (`--readme`, its older name, still works)."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"


def as_measured(config: Any, codec: str) -> tuple[Any, str]:
    """The rig (a RigConfig) `codec` is measured on, and its name in a table: `config`, or, for a
    codec that misreads a projector whose light is not linear in the level (Codec.needs_linear_light:
    cued_phase's 3 steps), the same with the simulated projectors' gamma at 1, as a DLP shows 8-bit
    patterns."""
    from rig.config import config_from_dict
    from rig.patterns import codec_class

    size = tuple(config.projectors[0].resolution)
    if not codec_class(codec)(size, getattr(config.scan, codec, None)).needs_linear_light:
        return config, codec
    data = config.model_dump(mode="json")
    for projector in data["projectors"]:
        if projector.get("sim") is not None:
            projector["sim"]["gamma"] = 1.0
    return config_from_dict(data, f"{codec} on a linear projector"), f"{codec} (linear projector)"


def replace_block(name: str, text: str) -> None:
    """Rewrite the block `name` in whichever page of the manual holds it, signed (provenance())."""
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    for page in (README, *sorted((REPO / "docs").rglob("*.md"))):
        content = page.read_text()
        if start in content and end in content:
            head, rest = content.split(start, 1)
            _, tail = rest.split(end, 1)
            page.write_text(f"{head}{start}\n{text.strip()}\n\n{provenance()}\n{end}{tail}")
            return
    raise SystemExit(f"no page of the manual (README.md, docs/) has a {start} ... {end} block")


def provenance() -> str:
    """Which command wrote a block, when, and on what machine: the line under every bench table."""
    script = Path(sys.argv[0]).name
    return (
        f"<small>Written by `python bench/{script} --docs` on {dt.date.today().isoformat()}: "
        f"{cpu_name()}, {os.cpu_count()} cores, Python {platform.python_version()}.</small>"
    )


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def markdown_table(header: list[str], rows: list[list[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


ACCURACY_HEADER = [
    "codec",
    "frames",
    "MB captured",
    "points",
    "rms mm",
    "p95 mm",
    "over 1 mm",
    "over 5 mm",
    "rms along ray mm",
    "over 1 mm along ray",
    "completeness",
]


def accuracy_cells(r: dict[str, Any], completeness_digits: int) -> list[object]:
    """The cells under ACCURACY_HEADER for one measured scan."""
    return [
        r["codec"],
        r["frames"],
        r["mb_captured"],
        r["points"],
        f"{r['rms_mm']:.3f}",
        f"{r['p95_mm']:.3f}",
        f"{100 * r['over_1mm_fraction']:.2f} %",
        r["outliers_over_5mm"],
        f"{r['ray_rms_mm']:.3f}",
        f"{100 * r['ray_over_1mm_fraction']:.2f} %",
        f"{r['completeness']:.{completeness_digits}f}",
    ]


def run(
    doc: str,
    block: str,
    measure: Callable[[], dict[str, Any]],
    table: Callable[[dict[str, Any]], str],
    more: dict[str, Callable[[dict[str, Any]], str]] | None = None,
) -> None:
    """A benchmark's command line: measure, print one JSON object, and with --docs rewrite the
    manual's block `block` with the table made from the measurement (and each of `more`'s blocks with
    what its function makes of it)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--docs", "--readme", dest="docs", action="store_true", help=f"rewrite the {block} block")
    args = parser.parse_args()
    measured = measure()
    print(json.dumps(measured))
    if args.docs:
        replace_block(block, table(measured))
        for name, make in (more or {}).items():  # other blocks from the same measurement
            replace_block(name, make(measured))
