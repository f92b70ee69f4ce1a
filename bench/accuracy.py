"""Accuracy of every codec on several simulated scenes; prints one JSON object.

python bench/accuracy.py            # JSON
python bench/accuracy.py --readme   # also rewrite the accuracy table in README.md
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, replace_block

from rig.config import RigConfig, load_config
from rig.evaluate import evaluate_pair
from rig.patterns import codec_names
from rig.rig import open_rig
from rig.scan import run_scan

REPO = Path(__file__).resolve().parent.parent
SCENES: dict[str, dict[str, object]] = {
    "sphere_on_plane": {"kind": "sphere_on_plane"},
    "plane": {"kind": "plane"},
    "box": {"kind": "box"},
    "terrain": {"kind": "terrain"},
    "blob.ply": {"kind": "mesh", "path": str(REPO / "config/meshes/blob.ply"), "fit_size_mm": 150.0},
}


def measure(config: RigConfig, codec: str) -> dict[str, object]:
    with open_rig(config) as rig:
        result = run_scan(rig, codec)
        pair = result.pairs[0]
        metrics = evaluate_pair(pair, rig.sim.ground_truth(0, 0), rig.sim)  # type: ignore[union-attr]
    return {
        "frames": result.frames_projected,
        "mb_captured": round(result.bytes_captured / 1e6, 1),
        **{k: (round(v, 4) if isinstance(v, float) else v) for k, v in metrics.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--readme", action="store_true", help="rewrite the accuracy table in README.md")
    args = parser.parse_args()
    base = load_config()
    results = []
    for scene, spec in SCENES.items():
        config = base.with_scene(spec)
        for codec in codec_names():
            results.append({"scene": scene, "codec": codec, **measure(config, codec)})
    out = {
        "benchmark": "accuracy",
        "machine": platform.machine(),
        "python": platform.python_version(),
        "bench": "config/sim.yaml (1280x1024 camera, 1024x768 projector, 600 mm, 200 mm baseline)",
        "results": results,
    }
    print(json.dumps(out))
    if args.readme:
        rows = [
            [
                r["scene"],
                r["codec"],
                r["frames"],
                r["mb_captured"],
                r["points"],
                f"{r['rms_mm']:.3f}",
                f"{r['p95_mm']:.3f}",
                f"{r['completeness']:.4f}",
            ]
            for r in results
        ]
        header = [
            "scene",
            "codec",
            "frames",
            "MB captured",
            "points",
            "rms mm",
            "p95 mm",
            "completeness",
        ]
        replace_block(
            "accuracy-table", markdown_table(header, rows) + "\n\nProduced by `python bench/accuracy.py --readme`."
        )


if __name__ == "__main__":
    main()
