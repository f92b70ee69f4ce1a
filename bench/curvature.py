"""Curvature of a scanned surface against the truth: how noise biases the principal curvatures and
what floor it leaves on flat surfaces, at several smoothing radii. One phase scan of the default
bench (a sphere of radius 60 mm on a plane); prints one JSON object; with --docs also rewrites
the curvature table in the manual (docs/).

    python bench/curvature.py [--docs] [--radii 2.5,5,10]

On the sphere (points farther than 1.5 radii from its rim, so every fit sees sphere only): the
median of the mean curvature, of k1 and of k2, each divided by the true 1/60 per mm. On the bench
plane (points over 15 mm from the sphere): the median and 90th percentile of |k1|, per mm.
"""

from __future__ import annotations

import argparse
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
from rig.config import SphereOnPlaneScene, load_config
from rig.geometry.curvature import principal_curvatures
from rig.pipeline.scan import run_scan


def measure(radii: list[float]) -> dict[str, Any]:
    config = load_config().with_codec("phase")
    scene = config.simulation.scene if config.simulation else None
    assert isinstance(scene, SphereOnPlaneScene), "the default bench is a sphere on a plane"
    centre = np.array([*scene.position_mm, scene.radius_mm])
    with open_rig(config) as rig:
        result = run_scan(rig)
        viewpoint = rig.camera_models[0].center
    points = result.cloud.points
    rows = []
    for radius in radii:
        t0 = time.perf_counter()
        c = principal_curvatures(points, viewpoint, radius_mm=radius)
        seconds = time.perf_counter() - t0
        from_centre = np.linalg.norm(c.points - centre, axis=1)
        on_sphere = c.valid & (np.abs(from_centre - scene.radius_mm) < 1.0) & (c.points[:, 2] > 1.5 * radius + 5.0)
        on_plane = c.valid & (np.abs(c.points[:, 2]) < 1.0) & (from_centre > scene.radius_mm + 15.0)
        true = 1.0 / scene.radius_mm
        rows.append(
            {
                "radius_mm": radius,
                "sphere_points": int(on_sphere.sum()),
                "mean_over_true": round(float(np.median(0.5 * (c.k1 + c.k2)[on_sphere]) / true), 3),
                "k1_over_true": round(float(np.median(c.k1[on_sphere]) / true), 3),
                "k2_over_true": round(float(np.median(c.k2[on_sphere]) / true), 3),
                "plane_points": int(on_plane.sum()),
                "flat_k1_median_per_mm": round(float(np.median(np.abs(c.k1[on_plane]))), 4),
                "flat_k1_p90_per_mm": round(float(np.percentile(np.abs(c.k1[on_plane]), 90)), 4),
                "seconds": round(seconds, 2),
            }
        )
    return {"points": len(points), "sphere_radius_mm": scene.radius_mm, "rows": rows}


def readme_table(report: dict[str, Any], default_radius: float) -> str:
    r = report["sphere_radius_mm"]
    header = ["radius", f"mean curvature / (1/{r:g})", f"k1 / (1/{r:g})", f"k2 / (1/{r:g})"]
    header.append("flat bench: median, p90 of abs(k1) per mm")
    rows = [
        [
            f"{row['radius_mm']:g} mm" + (" (default)" if row["radius_mm"] == default_radius else ""),
            f"{row['mean_over_true']:.3f}",
            f"{row['k1_over_true']:.3f}",
            f"{row['k2_over_true']:.3f}",
            f"{row['flat_k1_median_per_mm']:.4f}, {row['flat_k1_p90_per_mm']:.4f}",
        ]
        for row in report["rows"]
    ]
    return markdown_table(header, rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite the manual's curvature table"
    )
    parser.add_argument("--radii", default="2.5,5,10", help="smoothing radii, mm (2.5,5,10)")
    args = parser.parse_args()
    radii = [float(r) for r in args.radii.split(",") if r]
    t0 = time.perf_counter()
    report = measure(radii)
    default_radius = load_config().scan.adaptive.curvature_radius_mm
    print(
        json.dumps(
            {
                "benchmark": "curvature",
                "python": platform.python_version(),
                **report,
                "wall_s": round(time.perf_counter() - t0, 1),
            }
        )
    )
    if args.readme:
        replace_block("curvature", readme_table(report, default_radius))


if __name__ == "__main__":
    main()
