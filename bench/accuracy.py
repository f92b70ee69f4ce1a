"""Accuracy of every codec on several simulated scenes; prints one JSON object.

python bench/accuracy.py            # JSON
python bench/accuracy.py --docs   # also rewrite the accuracy table in the manual (docs/)
"""

from __future__ import annotations

import platform
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import ACCURACY_HEADER, accuracy_cells, as_measured, markdown_table, run

from rig.assembly import open_rig
from rig.config import RigConfig, load_config
from rig.evaluate.pairs import evaluate_pair
from rig.patterns import codec_names
from rig.pipeline.scan import run_scan

REPO = Path(__file__).resolve().parent.parent


def _scene_of(config_file: str) -> dict[str, object]:
    return load_config(REPO / "config" / config_file).model_dump(mode="json")["simulation"]["scene"]


SCENES: dict[str, dict[str, object]] = {
    "sphere_on_plane": {"kind": "sphere_on_plane"},
    "plane": {"kind": "plane"},
    "box": {"kind": "box"},
    "terrain": {"kind": "terrain"},
    "steps (config/sim-steps.yaml)": _scene_of("sim-steps.yaml"),
    "steps, edges along x": {**_scene_of("sim-steps.yaml"), "rotation_deg": [0.0, 0.0, 90.0]},
    "blocks (config/sim-blocks.yaml)": _scene_of("sim-blocks.yaml"),
    "blob.ply": {"kind": "mesh", "path": str(REPO / "config/meshes/blob.ply"), "fit_size_mm": 150.0},
}


def measure(config: RigConfig, codec: str) -> dict[str, object]:
    with open_rig(config) as rig:
        result = run_scan(rig, codec)
        pair = result.pairs[0]
        metrics = evaluate_pair(pair, rig.truth.ground_truth(0, 0), rig.truth)  # type: ignore[union-attr]
    return {
        "frames": result.frames_projected,
        "mb_captured": round(result.bytes_captured / 1e6, 1),
        **{k: (round(v, 4) if isinstance(v, float) else v) for k, v in metrics.items()},
    }


def measure_all() -> dict[str, object]:
    base = load_config()
    results = []
    for scene, spec in SCENES.items():
        config = base.with_scene(spec)
        for codec in codec_names():
            measured_on, label = as_measured(config, codec)
            results.append({"scene": scene, "codec": label, **measure(measured_on, codec)})
    return {
        "benchmark": "accuracy",
        "machine": platform.machine(),
        "python": platform.python_version(),
        "bench": "config/sim.yaml (1280x1024 camera, 1024x768 projector, 600 mm, 200 mm baseline)",
        "results": results,
    }


def table(measured: dict[str, Any]) -> str:
    rows = [[r["scene"], *accuracy_cells(r, 4)] for r in measured["results"]]
    return markdown_table(["scene", *ACCURACY_HEADER], rows)


def headline(measured: dict[str, Any]) -> str:
    """The README's table: every codec on the default scene."""
    rows = [
        [
            r["codec"],
            r["frames"],
            f"{r['points']:,}",
            f"{r['rms_mm']:.3f}",
            f"{r['p95_mm']:.3f}",
            f"{r['completeness']:.3f}",
        ]
        for r in measured["results"]
        if r["scene"] == "sphere_on_plane"
    ]
    header = ["codec", "frames", "points", "rms mm", "p95 mm", "completeness"]
    return (
        markdown_table(header, rows)
        + "\n\nThe default simulated bench (a sphere on a plane), against its ground truth."
    )


def main() -> None:
    run(__doc__ or "", "accuracy-table", measure_all, table, {"headline-results": headline})


if __name__ == "__main__":
    main()
