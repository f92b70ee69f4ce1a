"""Planned rings against their promise, on shapes the planner was never tuned on: a face, a torus,
steps, a smooth blob, a saddle and a cylinder, each on the bench plane, at tolerances 0.1, 0.2 and
0.5 mm. Per shape and tolerance: the plan (or the planner's refusal and its reason), the surface's
area-weighted p95 on the object alone (the bench plane left out) and on its worst region, the
coverage of each region between its rings, the inner disc, and the economy beside a dense scan
(the pilot's codec) and 32 evenly spaced rings: frames, bytes, points, decode and surface time.
Prints one JSON object; with --docs also rewrites the economy table in the manual (docs/) and draws
docs/images/rings_economy.png.

    python bench/rings_economy.py [--docs] [--shapes face,torus,steps,blob,saddle,cylinder]
    python bench/rings_economy.py --docs --report run.json   # the docs from a run's printed JSON

A plan keeps its promise when the object's area-weighted p95 and every surface region's are at most
the tolerance and the surface covers at least 95 % of the object between its rings; the pilot's cost is counted once per
shape (a plan is made once for a kind of object and reused).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, replace_block

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.errors import PlanError
from rig.evaluate.pairs import evaluate_pair
from rig.opened_rig import Rig
from rig.pipeline.results import ScanResult
from rig.pipeline.scan import run_scan
from rig.plan.ring_plan import pilot_views, plan_rings
from rig.service.adaptive import with_plan
from rig.store.ply import mesh_ply_bytes, ply_chunks

ROOT = Path(__file__).resolve().parent.parent
TOLERANCES = [0.1, 0.2, 0.5]
UNIFORM_RINGS = 32
MIN_COVERAGE = 0.95
IMAGE = ROOT / "docs/images/rings_economy.png"


def shape_meshes(folder: Path) -> dict[str, dict[str, Any]]:
    """The scenes: the face and blob meshes the project keeps, and a torus, a saddle and a cylinder
    made here (each scaled to size by the simulator)."""
    torus = trimesh.creation.torus(major_radius=0.35, minor_radius=0.15, major_sections=96, minor_sections=48)
    cylinder = trimesh.creation.cylinder(radius=0.3, height=1.0, sections=128)
    cylinder.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))  # lying on the plane
    n = 120
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    index = np.arange(n * n).reshape(n, n)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel()
    saddle = trimesh.Trimesh(
        np.column_stack([x.ravel(), y.ravel(), 0.3 * (x**2 - y**2).ravel() + 0.4]),
        np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])]),
    )
    made = {"torus": torus, "saddle": saddle, "cylinder": cylinder}
    paths = {name: folder / f"{name}.ply" for name in made}
    for name, mesh in made.items():
        mesh.export(paths[name])
    meshes = ROOT / "config/meshes"
    return {
        "face": {"kind": "mesh", "path": str(meshes / "face.ply"), "fit_size_mm": 200.0},
        "torus": {"kind": "mesh", "path": str(paths["torus"]), "fit_size_mm": 180.0},
        "steps": {"kind": "steps"},
        "blob": {"kind": "mesh", "path": str(meshes / "blob.ply"), "fit_size_mm": 160.0},
        "saddle": {"kind": "mesh", "path": str(paths["saddle"]), "fit_size_mm": 180.0},
        "cylinder": {"kind": "mesh", "path": str(paths["cylinder"]), "fit_size_mm": 160.0},
    }


def scene_config(scene: dict[str, Any]) -> Any:
    data = load_config().model_dump(mode="json")
    data["simulation"]["scene"] = scene
    return config_from_dict(data, "rings economy")


def with_uniform_rings(rig: Rig, count: int) -> Rig:
    data = rig.config.model_dump(mode="json")
    data["scan"]["codec"] = "rings"
    data["scan"]["rings"].update(rings=count, radii_px=None)
    return dataclasses.replace(rig, config=config_from_dict(data, f"{count} rings"))


def costs(result: ScanResult) -> dict[str, Any]:
    """What a scan cost: frames, bytes captured, points, its mesh, times, and what it stores (the
    cloud's and the mesh's PLY files, as a scan directory holds them)."""
    timings = result.timings_ms
    stored = sum(len(chunk) for chunk in ply_chunks(result.cloud))
    if result.mesh is not None:
        stored += len(mesh_ply_bytes(result.mesh))
    return {
        "frames": result.frames_projected,
        "bytes": result.bytes_captured,
        "points": len(result.cloud),
        "stored_bytes": stored,
        "mesh_vertices": None if result.mesh is None else len(result.mesh.vertices),
        "decode_ms": round(timings.get("decode_ms", 0.0), 1),
        "surface_ms": round(timings.get("surface_ms", 0.0), 1) if "surface_ms" in timings else None,
    }


def judged(rig: Rig, result: ScanResult) -> dict[str, Any]:
    assert rig.truth is not None
    m = evaluate_pair(result.pairs[0], rig.truth.ground_truth(0, 0), rig.truth)
    keys = ("surface_object_p95_mm", "surface_worst_region_p95_mm", "surface_object_coverage", "surface_coverage")
    keys += ("surface_inner_disc_coverage", "surface_object_promised", "surface_object_lit_coverage")
    return {**{k: _round(m.get(k)) for k in keys}, "surface_object_missed": m.get("surface_object_missed")}


def _round(value: Any) -> Any:
    return round(float(value), 4) if isinstance(value, float | np.floating) else value


def measure_shape(name: str, scene: dict[str, Any]) -> dict[str, Any]:
    config = scene_config(scene)
    with open_rig(config) as rig:
        pilot = run_scan(rig, config.scan.adaptive.pilot_codec)
        uniform = run_scan(with_uniform_rings(rig, UNIFORM_RINGS), "rings")
        views = pilot_views(pilot, rig.camera_models, rig.projector_models)
        planned = []
        for tolerance in TOLERANCES:
            t0 = time.perf_counter()
            try:
                plan = plan_rings(views, config.scan.adaptive, tolerance, method=config.scan.surface.interpolant)
            except PlanError as exc:
                planned.append({"tolerance_mm": tolerance, "refused": str(exc)})
                continue
            plan_s = time.perf_counter() - t0
            result = run_scan(with_plan(rig, plan), "rings")
            figures = judged(rig, result)
            planned.append(
                {
                    "tolerance_mm": tolerance,
                    "rings": plan.rings,
                    **figures,
                    **costs(result),
                    "keeps_promise": _keeps(figures, tolerance),
                    "plan_s": round(plan_s, 1),
                }
            )
        return {
            "shape": name,
            "dense": {"codec": pilot.codec, **costs(pilot)},
            "uniform": {"rings": UNIFORM_RINGS, **judged(rig, uniform), **costs(uniform)},
            "planned": planned,
        }


def _keeps(figures: dict[str, Any], tolerance: float) -> bool:
    """The promise: the object's p95 and every region's within the tolerance, the object covered."""
    p95, covered = figures["surface_object_p95_mm"], figures["surface_object_coverage"]
    worst = figures["surface_worst_region_p95_mm"]
    within = p95 is not None and p95 <= tolerance and worst is not None and worst <= tolerance
    return within and covered is not None and covered >= MIN_COVERAGE


def plot(results: list[dict[str, Any]], path: Path) -> None:
    """The object's area-weighted p95 against the tolerance asked for (log-log), a marker per shape;
    the diagonal is the promise. Refusals are drawn at the bottom as crosses."""
    size, margin = 520, 60
    canvas = np.full((size, size + 160, 3), 255, np.uint8)
    low, high = np.log(0.02), np.log(5.0)

    def to_px(x: float, y: float) -> tuple[int, int]:
        fx = (np.log(x) - low) / (high - low)
        fy = (np.log(max(y, 0.02)) - low) / (high - low)
        return int(margin + fx * (size - 1.5 * margin)), int(size - margin - fy * (size - 1.5 * margin))

    for value in (0.05, 0.1, 0.2, 0.5, 1.0, 2.0):
        x, y = to_px(value, value)
        cv2.line(canvas, (x, margin // 2), (x, size - margin), (232, 232, 232), 1)
        cv2.line(canvas, (margin, y), (size - margin // 2, y), (232, 232, 232), 1)
        cv2.putText(canvas, f"{value:g}", (x - 10, size - margin + 18), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        cv2.putText(canvas, f"{value:g}", (8, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    cv2.line(canvas, to_px(0.02, 0.02), to_px(5.0, 5.0), (0, 0, 0), 1, cv2.LINE_AA)
    colours = [(200, 80, 0), (0, 140, 0), (0, 0, 210), (160, 0, 160), (0, 150, 200), (90, 90, 90)]
    for k, shape in enumerate(results):
        colour = colours[k % len(colours)]
        for p in shape["planned"]:
            if "refused" in p:
                cv2.drawMarker(canvas, to_px(p["tolerance_mm"], 0.02), colour, cv2.MARKER_TILTED_CROSS, 10, 2)
            elif p["surface_object_p95_mm"] is not None:
                cv2.circle(canvas, to_px(p["tolerance_mm"], p["surface_object_p95_mm"]), 6, colour, -1, cv2.LINE_AA)
        cv2.circle(canvas, (size + 20, 60 + 24 * k), 6, colour, -1, cv2.LINE_AA)
        cv2.putText(canvas, shape["shape"], (size + 34, 65 + 24 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1)
    black = (0, 0, 0)
    cv2.putText(canvas, "tolerance asked (mm)", (size // 2 - 60, size - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.5, black, 1)
    cv2.putText(canvas, "object p95 by area (mm)", (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), canvas)


def docs_table(results: list[dict[str, Any]]) -> str:
    header = ["shape", "tolerance mm", "rings", "object p95 mm", "worst region p95 mm", "object covered"]
    header += ["missed: disc, crowded, elsewhere", "inner disc", "promised", "lit object covered", "frames"]
    header += ["points", "stored MB", "decode ms", "surface ms", "kept"]
    rows = []
    for shape in results:
        for p in shape["planned"]:
            if "refused" in p:
                rows.append([shape["shape"], p["tolerance_mm"], "refused", *([""] * 12), "refused"])
                continue
            rows.append(
                [
                    *(shape["shape"], p["tolerance_mm"], p["rings"], p["surface_object_p95_mm"]),
                    *(p["surface_worst_region_p95_mm"], _percent(p["surface_object_coverage"]), _missed(p)),
                    *(_percent(p["surface_inner_disc_coverage"]), _percent(p.get("surface_object_promised"))),
                    *(_percent(p.get("surface_object_lit_coverage")), p["frames"], p["points"]),
                    *(_mb(p["stored_bytes"]), p["decode_ms"], p["surface_ms"]),
                    "yes" if p["keeps_promise"] else "**no**",
                ]
            )
    economy = [row for shape in results for row in _economy_rows(shape)]
    return (
        markdown_table(header, rows)
        + f"\n\nWhat each way of scanning the same shape costs, at {ECONOMY_TOLERANCE:g} mm (adaptive: the "
        "pilot and the planned scan; a plan reused for a kind of object pays the pilot once):\n\n"
        + markdown_table(ECONOMY_HEADER, economy)
    )


ECONOMY_TOLERANCE = 0.2
ECONOMY_HEADER = ["shape", "scan", "frames", "MB captured", "points", "decode ms", "surface ms", "stored MB"]
ECONOMY_HEADER += ["object p95 mm", "object covered"]


def _economy_rows(shape: dict[str, Any]) -> list[list[Any]]:
    """Dense, evenly spaced rings, the plan at ECONOMY_TOLERANCE and adaptive (its pilot added)."""
    dense, uniform = shape["dense"], shape["uniform"]
    planned = next((p for p in shape["planned"] if p["tolerance_mm"] == ECONOMY_TOLERANCE), None)
    rows = [_economy_row(shape["shape"], f"dense ({dense['codec']})", dense, None, None)]
    rows.append(_economy_row(shape["shape"], f"{UNIFORM_RINGS} even rings", uniform, *_accuracy(uniform)))
    if planned is None or "refused" in planned:
        rows.append([shape["shape"], "planned", *(["refused"] * (len(ECONOMY_HEADER) - 2))])
        return rows
    rows.append(_economy_row(shape["shape"], f"planned ({planned['rings']} rings)", planned, *_accuracy(planned)))
    adaptive = {k: planned[k] + dense[k] for k in ("frames", "bytes", "decode_ms")}
    adaptive.update({k: planned[k] for k in ("points", "surface_ms", "stored_bytes")})
    rows.append(_economy_row(shape["shape"], "adaptive (pilot + planned)", adaptive, *_accuracy(planned)))
    return rows


def _accuracy(figures: dict[str, Any]) -> tuple[Any, Any]:
    return figures["surface_object_p95_mm"], figures["surface_object_coverage"]


def _economy_row(shape: str, scan: str, cost: dict[str, Any], p95: Any, covered: Any) -> list[Any]:
    surface = "" if cost.get("surface_ms") is None else cost["surface_ms"]
    return [
        *(shape, scan, cost["frames"], _mb(cost["bytes"]), cost["points"], round(cost["decode_ms"], 1), surface),
        *(_mb(cost["stored_bytes"]), "" if p95 is None else p95, _percent(covered)),
    ]


def _missed(figures: dict[str, Any]) -> str:
    """Where the promised area of the object went uncovered, in % of it (rig.evaluate.wholeness)."""
    missed = figures.get("surface_object_missed") or {}
    parts = [missed.get(k) for k in ("inner_disc", "crowded", "elsewhere")]
    return "" if None in parts else ", ".join(f"{100 * v:.1f}" for v in parts) + " %"


def _mb(value: int) -> str:
    return f"{value / 1e6:.1f}"


def _percent(value: Any) -> str:
    return "" if value is None else f"{100 * value:.1f} %"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite the docs table and plot"
    )
    parser.add_argument("--shapes", default="face,torus,steps,blob,saddle,cylinder", help="comma-separated")
    parser.add_argument(
        "--report", type=Path, default=None, help="with --docs: write from this run's printed JSON, not a new run"
    )
    args = parser.parse_args()
    if args.report is not None:
        saved = json.loads(args.report.read_text())
        replace_block("rings-economy", docs_table(saved["shapes"]))
        plot(saved["shapes"], IMAGE)
        return
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        scenes = shape_meshes(Path(folder))
        names = [n for n in args.shapes.split(",") if n]
        unknown = [n for n in names if n not in scenes]
        if unknown:
            raise SystemExit(f"unknown shapes: {', '.join(unknown)}; known: {', '.join(scenes)}")
        results = [measure_shape(n, scenes[n]) for n in names]
    report = {
        "benchmark": "rings_economy",
        "python": platform.python_version(),
        "interpolant": load_config().scan.surface.interpolant,
        "tolerances_mm": TOLERANCES,
        "shapes": results,
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(report))
    if args.readme:
        replace_block("rings-economy", docs_table(results))
        plot(results, IMAGE)


if __name__ == "__main__":
    main()
