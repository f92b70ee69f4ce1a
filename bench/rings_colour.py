"""Colour between the rings: PSNR, RGB rms and CIEDE2000 of the colour interpolated from the ring
samples alone (L-NN, inverse distance, density-compensated), against the true albedo, beside the
white frame's colour at every pixel (the upper bound), on textured versions of the default bench.
The rings are the plan for `--tolerance` (non-uniform radii) and as many evenly spaced rings.
Prints one JSON object; with --docs also rewrites the colour table in the manual (docs/).

    python bench/rings_colour.py [--docs] [--tolerance 0.2] [--neighbours 8]

Every figure is on the mesh's vertices (every 2nd pixel: scan.surface.mesh_stride_px) that the
interpolated surface covers and the projector lights; see rig.evaluate.colour for how shading and
exposure are taken out before comparing.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, replace_block

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.evaluate.colour import colour_metrics
from rig.opened_rig import Rig
from rig.pipeline.colour import COLOUR_METHODS, interpolate_colour, sample_colours
from rig.pipeline.scan import run_scan
from rig.plan.ring_plan import pilot_views, plan_rings
from rig.service.adaptive import with_plan

ROOT = Path(__file__).resolve().parent.parent
TEXTURES: dict[str, dict[str, Any]] = {
    "gradient": {"kind": "gradient", "period_mm": 120.0},
    "chart": {"kind": "image", "path": str(ROOT / "config/textures/chart.png"), "size_mm": 240.0},
    "checker 20 mm": {"kind": "checker", "size_mm": 20.0},
    "stripes 30 mm": {"kind": "stripes", "period_mm": 30.0, "direction_mm": [1.0, 1.0, 0.0]},
}


def textured_config(texture: dict[str, Any]) -> Any:
    data = load_config().model_dump(mode="json")
    data["simulation"]["texture"] = texture
    for camera in data["cameras"]:
        camera["color"] = True
    return config_from_dict(data, "rings colour")


def with_rings(rig: Rig, count: int | None) -> Rig:
    data = rig.config.model_dump(mode="json")
    data["scan"]["codec"] = "rings"
    if count is not None:
        data["scan"]["rings"].update(rings=count, radii_px=None)
    return dataclasses.replace(rig, config=config_from_dict(data, "rings"))


def colour_figures(rig: Rig, sparse: Rig, neighbours: int) -> dict[str, Any]:
    """Per interpolant, and for the white frame, the colour metrics of one ring scan."""
    result = run_scan(sparse, "rings")
    pair = result.pairs[0]
    assert pair.surface is not None and pair.rings is not None and rig.truth is not None
    truth = rig.truth.ground_truth(0, 0)
    corr = pair.correspondence
    colours = sample_colours(corr.texture, pair.rings.camera_xy[pair.rings.kept], corr.full_scale)
    stride = sparse.config.scan.surface.mesh_stride_px
    figures: dict[str, Any] = {"rings": len(corr.samples.ring_radii_px) if corr.samples is not None else None}
    for method in COLOUR_METHODS:
        t0 = time.perf_counter()
        colour = interpolate_colour(pair.surface, colours, method, neighbours, stride)  # type: ignore[arg-type]
        seconds = time.perf_counter() - t0
        with_colour = dataclasses.replace(pair, surface=dataclasses.replace(pair.surface, colour=colour))
        m = colour_metrics(with_colour, truth)
        figures[method] = {**_figures(m, "colour"), "seconds": round(seconds, 3)}
        figures["white"] = _figures(m, "white_colour")
        figures["pixels"] = m["colour_pixels"]
    return figures


def _figures(metrics: dict[str, Any], prefix: str) -> dict[str, Any]:
    return {k: _round(metrics[f"{prefix}_{k}"]) for k in ("psnr_db", "rgb_rms", "delta_e2000")}


def _one(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def _round(value: Any) -> Any:
    return round(value, 3) if isinstance(value, float) else value


def measure(tolerance: float, neighbours: int) -> list[dict[str, Any]]:
    rows = []
    plan = None
    for name, texture in TEXTURES.items():
        config = textured_config(texture)
        with open_rig(config) as rig:
            if plan is None:  # the plan depends on the shape, not its colour: one pilot for all
                pilot = run_scan(rig, config.scan.adaptive.pilot_codec)
                views = pilot_views(pilot, rig.camera_models, rig.projector_models)
                plan = plan_rings(views, config.scan.adaptive, tolerance, method=config.scan.surface.interpolant)
            planned = colour_figures(rig, with_plan(rig, plan), neighbours)
            uniform = colour_figures(rig, with_rings(rig, plan.rings), neighbours)
        rows.append({"texture": name, "planned": planned, "uniform": uniform})
    return rows


def readme_table(rows: list[dict[str, Any]], tolerance: float) -> str:
    header = ["texture", "rings", "L-NN dB", "inverse distance dB", "density-compensated dB", "white frame dB"]
    header += ["dE2000 L-NN", "dE2000 density-compensated", "dE2000 white frame"]
    lines = []
    for row in rows:
        for kind, label in (("planned", f"planned for {tolerance} mm"), ("uniform", "as many, even")):
            f = row[kind]
            lines.append(
                [
                    row["texture"],
                    f"{f['rings']} ({label})",
                    *(_one(f[m]["psnr_db"]) for m in ("nearest", "idw", "area", "white")),
                    *(_one(f[m]["delta_e2000"]) for m in ("nearest", "area", "white")),
                ]
            )
    return markdown_table(header, lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite README.md's colour table"
    )
    parser.add_argument("--tolerance", type=float, default=0.2, help="the plan's tolerance, mm (0.2)")
    parser.add_argument("--neighbours", type=int, default=8, help="L of the interpolants (8)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    rows = measure(args.tolerance, args.neighbours)
    report = {
        "benchmark": "rings_colour",
        "python": platform.python_version(),
        "tolerance_mm": args.tolerance,
        "neighbours": args.neighbours,
        "rows": rows,
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(report, default=lambda v: v.item() if isinstance(v, np.generic) else str(v)))
    if args.readme:
        replace_block("rings-colour", readme_table(rows, args.tolerance))


if __name__ == "__main__":
    main()
