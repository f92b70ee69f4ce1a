"""The surface between the rings with each interpolant (scan.surface.interpolant) at the default 32
rings on the default simulated bench, against its truth. Prints one JSON object; with --docs
rewrites the interpolants block of docs/rings.md.

    python bench/interpolants.py [--docs]
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.evaluate.pairs import evaluate_on_bench
from rig.pipeline.scan import run_scan

INTERPOLANTS = {
    "linear": "the plane of each triangle",
    "quadratic": "default",
    "cubic": "SciPy's Clough-Tocher over the image",
}


def measure() -> dict[str, Any]:
    base = load_config().model_dump(mode="json")
    results = {}
    for name in INTERPOLANTS:
        base["scan"]["surface"]["interpolant"] = name
        with open_rig(config_from_dict(base, f"interpolant {name}")) as rig:
            metrics = evaluate_on_bench(rig, run_scan(rig, "rings").pairs[0])
        results[name] = {k: metrics[k] for k in ("surface_rms_mm", "surface_p95_mm", "surface_completeness")}
    return {"benchmark": "interpolants", "rings": 32, "results": results}


def table(m: dict[str, Any]) -> str:
    rows = [
        [f"`{name}` ({INTERPOLANTS[name]})", f"{r['surface_rms_mm']:.3f}", f"{r['surface_p95_mm']:.3f}",
         f"{r['surface_completeness']:.3f}"]
        for name, r in m["results"].items()
    ]  # fmt: skip
    return markdown_table(["interpolant", "surface rms mm", "p95 mm", "complete"], rows)


def main() -> None:
    run(__doc__ or "", "interpolants", measure, table)


if __name__ == "__main__":
    main()
