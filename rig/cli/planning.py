"""`slrig plan views`: the fewest heads that cover an object (the planner casts rays with the
simulator, so this command alone loads it). `plan rings` is rig.cli.ring_planning."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rig.assembly import build_scene
from rig.cli.common import scene_override
from rig.cli.ring_planning import cmd_plan_rings
from rig.config import load_config
from rig.errors import ConfigError
from rig.plan import confirm_on_bench, plan_views


def cmd_plan(args: argparse.Namespace) -> int:
    if args.what == "rings":
        return cmd_plan_rings(args)

    checks = [
        ("--coverage", 0.05 <= args.coverage <= 1.0, "0.05..1"),
        ("--candidates", 4 <= args.candidates <= 2000, "4..2000"),
        ("--max-angle", 5.0 <= args.max_angle <= 89.0, "5..89"),
        ("--baseline", 0.0 <= args.baseline <= 90.0, "0..90"),
        ("--min-elevation", -90.0 <= args.min_elevation < 90.0, "-90..90"),
    ]
    bad = [f"{flag}: outside {bounds}" for flag, ok, bounds in checks if not ok]
    if args.distance is not None and not 10.0 <= args.distance <= 100_000.0:
        bad.append("--distance: outside 10..100000 mm")
    if bad:
        raise ConfigError("plan views", bad)
    config = load_config(args.config)
    if args.scene:
        config = scene_override(config, args.scene)
    if config.simulation is None:
        raise ConfigError("--scene", ["--scene: a real rig's config has no object; name one (box, sphere, a mesh)"])
    scene_config = config.simulation.scene
    if hasattr(scene_config, "plane") and isinstance(scene_config.plane, bool):  # the object alone
        config = config.with_scene({**scene_config.model_dump(mode="json"), "plane": False})
    scene = build_scene(config.simulation)  # type: ignore[arg-type]
    positions = _candidate_positions(args.poses) if args.poses else None
    plan = plan_views(
        scene,
        args.coverage,
        args.candidates,
        args.distance,
        args.max_angle,
        args.baseline,
        args.min_elevation,
        positions=positions,
    )
    report = plan.as_dict()
    if args.confirm:
        report["confirmed_coverage"] = round(confirm_on_bench(scene, plan), 4)
    if args.json:
        print(json.dumps(report, allow_nan=False))
        return 0
    print(f"{len(plan.cameras)} cameras and {len(plan.projectors)} projectors cover {plan.coverage:.1%} of the object")
    for kind in ("cameras", "projectors"):
        for pose in report[kind]:  # type: ignore[attr-defined]
            print(f"  {kind[:-1]} at {pose['position_mm']} looking at {pose['look_at_mm']}")
    if args.confirm:
        print(f"the simulated bench confirms {report['confirmed_coverage']:.1%}")
    return 0


def _candidate_positions(path: Path) -> Any:
    try:
        data = yaml.safe_load(path.read_text())
        positions = np.asarray(data, dtype=float)
    except (OSError, yaml.YAMLError, ValueError, TypeError) as exc:
        raise ConfigError(str(path), [f"--poses: {path} is not a YAML list of [x, y, z] positions ({exc})"]) from None
    if positions.ndim != 2 or positions.shape[1] != 3 or not 1 <= len(positions) <= 5000:
        raise ConfigError(str(path), [f"--poses: {path} must list 1 to 5000 positions [x, y, z] (mm)"])
    if not np.isfinite(positions).all():
        raise ConfigError(str(path), [f"--poses: {path} has a position that is not a finite number"])
    return positions
