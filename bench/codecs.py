"""The four codecs on the default scene, side by side: pattern economy and accuracy, as the
dissertation compares codecs by data size. Prints one JSON object.

    python bench/codecs.py            # JSON
    python bench/codecs.py --readme   # also rewrite the codec table in README.md
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, replace_block
from speed import reconstruction

from rig.config import load_config
from rig.evaluate import evaluate_pair
from rig.rig import open_rig
from rig.scan import run_scan

CODECS = ("gray", "phase", "rings", "radial")


def measure(codec: str) -> dict[str, object]:
    with open_rig(load_config().with_codec(codec)) as rig:
        result = run_scan(rig)
        pair = result.pairs[0]
        assert rig.sim is not None
        metrics = evaluate_pair(pair, rig.sim.ground_truth(0, 0), rig.sim)
    timing = reconstruction(codec)
    return {
        "codec": codec,
        "frames": result.frames_projected,
        "mb_captured": round(result.bytes_captured / 1e6, 1),
        "points": metrics["points"],
        "rms_mm": round(float(metrics["rms_mm"]), 4),
        "p95_mm": round(float(metrics["p95_mm"]), 4),
        "completeness": round(float(metrics["completeness"]), 4),
        "decode_triangulate_ms": timing["decode_triangulate_ms"],
        "counts": pair.counts,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--readme", action="store_true", help="rewrite the codec table in README.md")
    args = parser.parse_args()
    results = [measure(codec) for codec in CODECS]
    print(
        json.dumps(
            {
                "benchmark": "codecs",
                "scene": "sphere_on_plane (config/sim.yaml)",
                "python": platform.python_version(),
                "results": results,
            }
        )
    )
    if args.readme:
        header = [
            "codec",
            "frames",
            "MB captured",
            "points",
            "rms mm",
            "p95 mm",
            "completeness",
            "decode+triangulate ms",
        ]
        rows = [
            [
                r["codec"],
                r["frames"],
                r["mb_captured"],
                r["points"],
                f"{r['rms_mm']:.3f}",
                f"{r['p95_mm']:.3f}",
                f"{r['completeness']:.3f}",
                r["decode_triangulate_ms"],
            ]
            for r in results
        ]
        replace_block(
            "codec-table", markdown_table(header, rows) + "\n\nProduced by `python bench/codecs.py --readme`."
        )


if __name__ == "__main__":
    main()
