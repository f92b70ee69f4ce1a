"""Replace a marked block of the manual (README.md or a page of docs/) with a table a benchmark
produced. (`--readme` keeps its name: the tables lived in the README before the manual moved.)"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"


def replace_block(name: str, text: str) -> None:
    """Rewrite the block `name` in whichever page of the manual holds it."""
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    for page in (README, *sorted((REPO / "docs").rglob("*.md"))):
        content = page.read_text()
        if start in content and end in content:
            head, rest = content.split(start, 1)
            _, tail = rest.split(end, 1)
            page.write_text(f"{head}{start}\n{text.strip()}\n{end}{tail}")
            return
    raise SystemExit(f"no page of the manual (README.md, docs/) has a {start} ... {end} block")


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


def run(doc: str, block: str, measure: Callable[[], dict[str, Any]], table: Callable[[dict[str, Any]], str]) -> None:
    """A benchmark's command line: measure, print one JSON object, and with --readme rewrite the
    manual's block `block` with the table made from the measurement."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--readme", action="store_true", help=f"rewrite the {block} block of the manual")
    args = parser.parse_args()
    measured = measure()
    print(json.dumps(measured))
    if args.readme:
        replace_block(block, table(measured))
