"""Error of the surface interpolated between the rings against the ring count, on the sphere, the
terrain and the face relief (config/meshes/face.ply): N evenly spaced rings for N = 4 ... 64, and
the planned non-uniform rings for several tolerances, with the planner's N_min by each criterion.
Prints one JSON object; with --docs also rewrites the economy table in the manual (docs/) and draws
docs/images/rings_economy.png.

    python bench/rings_economy.py [--docs] [--scenes sphere,terrain,face]

A ring set meets a tolerance e_tol when its interpolated surface's rms distance to the true surface
is at most e_tol (the default interpolant, quadratic); completeness (the fraction of the lit object
the surface covers within 1 mm) is reported beside it.
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

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, replace_block

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.evaluate.pairs import evaluate_pair
from rig.pipeline.scan import run_scan
from rig.plan.ring_plan import pilot_views, plan_rings
from rig.rig import Rig
from rig.service.adaptive import with_plan

ROOT = Path(__file__).resolve().parent.parent
SCENES: dict[str, dict[str, Any] | None] = {
    "sphere": None,  # the default bench: a sphere of radius 60 mm on a plane
    "terrain": {"kind": "terrain", "size_mm": 300.0, "amplitude_mm": 30.0},
    "face": {"kind": "mesh", "path": str(ROOT / "config/meshes/face.ply"), "fit_size_mm": 200.0},
}
COUNTS = [4, 6, 8, 10, 12, 14, 16, 20, 24, 28, 32, 40, 48, 64]
TOLERANCES = [0.05, 0.1, 0.2]
IMAGE = ROOT / "docs/images/rings_economy.png"


def scene_config(scene: dict[str, Any] | None) -> Any:
    data = load_config().model_dump(mode="json")
    if scene is not None:
        data["simulation"]["scene"] = scene
    return config_from_dict(data, "rings economy")


def with_uniform_rings(rig: Rig, count: int) -> Rig:
    data = rig.config.model_dump(mode="json")
    data["scan"]["codec"] = "rings"
    data["scan"]["rings"].update(rings=count, radii_px=None)
    return dataclasses.replace(rig, config=config_from_dict(data, f"{count} rings"))


def surface_figures(rig: Rig, sparse: Rig) -> dict[str, Any]:
    result = run_scan(sparse, "rings")
    assert rig.truth is not None
    m = evaluate_pair(result.pairs[0], rig.truth.ground_truth(0, 0), rig.truth)
    return {
        "rms_mm": _round(m.get("surface_rms_mm")),
        "p95_mm": _round(m.get("surface_p95_mm")),
        "completeness": _round(m.get("surface_completeness")),
        "frames": result.frames_projected,
    }


def _round(value: Any) -> Any:
    return round(value, 4) if isinstance(value, float) else value


def measure_scene(name: str, scene: dict[str, Any] | None) -> dict[str, Any]:
    config = scene_config(scene)
    with open_rig(config) as rig:
        uniform = [{"rings": n, **surface_figures(rig, with_uniform_rings(rig, n))} for n in COUNTS]
        pilot = run_scan(rig, config.scan.adaptive.pilot_codec)
        views = pilot_views(pilot, rig.camera_models, rig.projector_models)
        planned = []
        for tolerance in TOLERANCES:
            t0 = time.perf_counter()
            plan = plan_rings(views, config.scan.adaptive, tolerance, method=config.scan.surface.interpolant)
            plan_s = time.perf_counter() - t0
            figures = surface_figures(rig, with_plan(rig, plan))
            smallest = next((u["rings"] for u in uniform if _meets(u, tolerance)), None)
            planned.append(
                {
                    "tolerance_mm": tolerance,
                    "rings": plan.rings,
                    **figures,
                    "meets": _meets(figures, tolerance),
                    "smallest_uniform_meeting": smallest,
                    "fewer_than_uniform": None if smallest is None else round(1.0 - plan.rings / smallest, 3),
                    "n_min": {k: v["rings"] for k, v in plan.criteria.items()},
                    "plan_s": round(plan_s, 1),
                }
            )
    return {"scene": name, "uniform": uniform, "planned": planned}


def _meets(figures: dict[str, Any], tolerance: float) -> bool:
    return figures["rms_mm"] is not None and figures["rms_mm"] <= tolerance


def plot(results: list[dict[str, Any]], path: Path) -> None:
    """rms against ring count (log-log), one panel per scene: uniform as a line, planned as dots."""
    width, height, margin = 420, 320, 48
    canvas = np.full((height + 24, width * len(results), 3), 255, np.uint8)  # a strip below for the legend
    x_range, y_range = (np.log(3.5), np.log(80.0)), (np.log(0.01), np.log(20.0))

    def to_px(panel: int, n: float, e: float) -> tuple[int, int]:
        fx = (np.log(n) - x_range[0]) / (x_range[1] - x_range[0])
        fy = (np.log(max(e, 0.01)) - y_range[0]) / (y_range[1] - y_range[0])
        column = panel * width + margin + fx * (width - 1.5 * margin)
        return int(column), int(height - margin - fy * (height - 1.6 * margin))

    for panel, scene in enumerate(results):
        x0 = panel * width
        cv2.putText(canvas, scene["scene"], (x0 + margin, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
        for n in (4, 8, 16, 32, 64):
            p = to_px(panel, n, 0.01)
            cv2.line(canvas, (p[0], margin - 10), (p[0], p[1]), (230, 230, 230), 1)
            cv2.putText(canvas, str(n), (p[0] - 6, p[1] + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        for e in (0.01, 0.05, 0.2, 1.0, 5.0):
            p = to_px(panel, 3.5, e)
            cv2.line(canvas, (p[0], p[1]), (x0 + width - margin // 2, p[1]), (230, 230, 230), 1)
            cv2.putText(canvas, f"{e:g}", (x0 + 4, p[1] + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        line = [to_px(panel, u["rings"], u["rms_mm"]) for u in scene["uniform"] if u["rms_mm"] is not None]
        cv2.polylines(canvas, [np.array(line, np.int32)], False, (180, 80, 0), 2, cv2.LINE_AA)
        for p in scene["planned"]:
            if p["rms_mm"] is not None:
                cv2.circle(canvas, to_px(panel, p["rings"], p["rms_mm"]), 5, (0, 0, 220), -1, cv2.LINE_AA)
            tol = to_px(panel, 80.0, p["tolerance_mm"])
            cv2.drawMarker(canvas, (tol[0] - 6, tol[1]), (0, 0, 220), cv2.MARKER_TRIANGLE_DOWN, 8)
        marks = scene["planned"][0]["n_min"] if scene["planned"] else {}
        for key, letter, colour in (
            ("curvature_frequency", "F", (40, 150, 40)),
            ("sagitta_uniform", "S", (0, 120, 230)),
        ):
            if key in marks:
                x, y = to_px(panel, min(float(marks[key]), 78.0), 0.01)
                cv2.line(canvas, (x, y), (x, y - 14), colour, 2)
                cv2.putText(canvas, letter, (x - 4, y - 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv2.LINE_AA)
        cv2.putText(
            canvas, "rings", (x0 + width // 2, height - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA
        )
    legend = (
        "line: N uniform rings; dots: planned rings; triangles: tolerances; F, S: N_min at the tightest, "
        "by curvature frequency and by the sagitta bound (at the right edge: beyond 64); rms mm against rings, log-log"
    )
    cv2.putText(canvas, legend, (8, height + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (60, 60, 60), 1, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), canvas)


def readme_table(results: list[dict[str, Any]]) -> str:
    header = ["scene", "tolerance mm", "planned rings", "rms mm", "p95 mm", "complete", "meets"]
    header += ["smallest uniform meeting", "fewer", "N_min sagitta uniform", "N_min curvature frequency"]
    rows = []
    for scene in results:
        for p in scene["planned"]:
            fewer = "" if p["fewer_than_uniform"] is None else f"{100 * p['fewer_than_uniform']:.0f} %"
            smallest = p["smallest_uniform_meeting"] or "none of 4-64"
            rows.append(
                [
                    *(scene["scene"], p["tolerance_mm"], p["rings"], p["rms_mm"], p["p95_mm"], p["completeness"]),
                    *("yes" if p["meets"] else "**no**", smallest, fewer),
                    *(p["n_min"]["sagitta_uniform"], p["n_min"]["curvature_frequency"]),
                ]
            )
    uniform_header = ["scene"] + [str(n) for n in COUNTS]
    uniform_rows = [[s["scene"]] + [u["rms_mm"] for u in s["uniform"]] for s in results]
    return (
        markdown_table(header, rows)
        + "\n\nInterpolated-surface rms (mm) of N evenly spaced rings:\n\n"
        + markdown_table(uniform_header, uniform_rows)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite README.md's table and the plot"
    )
    parser.add_argument("--scenes", default=",".join(SCENES), help="comma-separated: " + ", ".join(SCENES))
    args = parser.parse_args()
    names = [n for n in args.scenes.split(",") if n]
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        raise SystemExit(f"unknown scenes: {', '.join(unknown)}; known: {', '.join(SCENES)}")
    t0 = time.perf_counter()
    results = [measure_scene(n, SCENES[n]) for n in names]
    report = {
        "benchmark": "rings_economy",
        "python": platform.python_version(),
        "interpolant": load_config().scan.surface.interpolant,
        "scenes": results,
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(report))
    if args.readme:
        replace_block("rings-economy", readme_table(results))
        plot(results, IMAGE)


if __name__ == "__main__":
    main()
