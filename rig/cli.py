"""The `slrig` command line: scan, eval.

Exit codes: 0 success; 1 the scan failed (device fault); 2 bad input (config, options, files).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from drivers.errors import DeviceError
from rig import __version__
from rig.assembly import open_rig
from rig.calibrate.response import RESPONSE_NAME, calibrate_response
from rig.calibrate.session import calibrate
from rig.config import SCENE_KINDS, RigConfig, load_config
from rig.doctor.checks import check, measure_latency, store_latencies
from rig.doctor.inventory import describe, inventory
from rig.errors import ConfigError, ScanError, SlrigError
from rig.evaluate.merged import evaluate_merge
from rig.evaluate.pairs import evaluate_on_bench
from rig.patterns import codec_class, codec_names
from rig.pipeline.scan import run_scan
from rig.progress import TerminalBar
from rig.service.tasks import scan_to_directory
from rig.store.scandir import new_scan_id

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
MESH_FIT_SIZE_MM = 150.0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="slrig", description="Structured-light 3D scanning rig.")
    parser.add_argument("--version", action="version", version=f"slrig {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--config",
            type=Path,
            default=None,
            help="rig description (YAML); default: the simulated bench, config/sim.yaml",
        )
        p.add_argument(
            "--codec", default=None, help=f"pattern codec: {', '.join(codec_names())} (default: the config's)"
        )
        p.add_argument("--json", action="store_true", help="print one JSON object instead of text")

    scan = sub.add_parser("scan", help="scan and write a scan directory (cloud.ply, depth, preview)")
    common(scan)
    scan.add_argument(
        "--out",
        type=Path,
        default=None,
        help="scan directory to create (must not exist); default <data_dir>/scans/<id>",
    )
    evaluate = sub.add_parser("eval", help="scan the simulated bench and measure it against ground truth")
    common(evaluate)
    evaluate.add_argument(
        "--scene",
        default=None,
        help=f"scene name ({', '.join(k for k in SCENE_KINDS if k != 'mesh')}) or a "
        f"PLY/OBJ/STL file (scaled to {MESH_FIT_SIZE_MM:.0f} mm)",
    )
    plan = sub.add_parser("plan", help="plan the fewest projector-camera heads that cover an object")
    plan.add_argument("what", choices=["views"])
    plan.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    plan.add_argument("--scene", default=None, help="box, sphere or a mesh file (default: the config's object)")
    plan.add_argument("--coverage", type=float, default=0.95, help="fraction of the surface to cover (0.95)")
    plan.add_argument("--candidates", type=int, default=120, help="candidate heads on a sphere (120)")
    plan.add_argument("--poses", type=Path, default=None, help="YAML list of candidate camera positions [x, y, z] mm")
    plan.add_argument("--distance", type=float, default=None, help="their distance, mm (4 x the object's radius)")
    plan.add_argument("--max-angle", type=float, default=65.0, help="steepest view of a surface, degrees (65)")
    plan.add_argument("--baseline", type=float, default=15.0, help="projector beside camera, degrees (15)")
    plan.add_argument("--min-elevation", type=float, default=-90.0, help="lowest head, degrees (-90: all round)")
    plan.add_argument("--confirm", action="store_true", help="render the plan on the simulated bench and measure it")
    plan.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    serve = sub.add_parser("serve", help="run the daemon: REST API (under /v1) and job queue for this rig")
    serve.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8750, help="TCP port (default 8750; 0: any free port)")
    serve.add_argument("--api-key-file", type=Path, default=None, help="file holding the API key (else $SLRIG_API_KEY)")
    devices = sub.add_parser("devices", help="list attached USB devices, video nodes, serial ports and OAK cameras")
    devices.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    doctor = sub.add_parser("doctor", help="check a rig config against this machine; --latency measures displays")
    doctor.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    doctor.add_argument(
        "--latency",
        action="store_true",
        help="measure each projector's display-to-capture latency and store it in <data_dir>",
    )
    doctor.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    cal = sub.add_parser("calibrate", help="calibrate cameras, projectors, or the whole rig into one world frame")
    cal.add_argument(
        "what",
        choices=["camera", "projector", "rig", "response"],
        help="camera: the cameras; projector or rig: cameras and projectors (a projector is "
        "calibrated against a camera); response: each projector's response (gamma)",
    )
    cal.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    cal.add_argument("--views", type=int, default=None, help="board poses to capture on the simulated bench")
    cal.add_argument(
        "--images",
        type=Path,
        default=None,
        help="read the views from this folder (view_NN/<camera>.png, view_NN/<projector>_<camera>/)",
    )
    cal.add_argument("--save-views", type=Path, default=None, help="also write the captured views to this folder")
    cal.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder for calibration.json/.yaml and coverage pictures; default <data_dir>/calibration",
    )
    cal.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    return parser


def _load(args: argparse.Namespace) -> RigConfig:
    if args.codec:
        codec_class(args.codec)  # an unknown name fails here, naming the known ones
    config = load_config(args.config)
    if args.codec:
        config = config.with_codec(args.codec)
    return config


def _scene_override(config: RigConfig, scene: str) -> RigConfig:
    if scene in SCENE_KINDS and scene != "mesh":
        return config.with_scene({"kind": scene})
    path = Path(scene)
    if path.is_file():
        return config.with_scene({"kind": "mesh", "path": str(path.resolve()), "fit_size_mm": MESH_FIT_SIZE_MM})
    names = ", ".join(k for k in SCENE_KINDS if k != "mesh")
    raise ConfigError("--scene", [f"--scene: {scene!r} is neither a scene name ({names}) nor a mesh file"])


def _progress(args: argparse.Namespace) -> TerminalBar | None:
    return TerminalBar() if sys.stderr.isatty() and not args.json else None


def cmd_scan(args: argparse.Namespace) -> int:
    config = _load(args)
    scan_id = new_scan_id()
    target = args.out if args.out is not None else config.output.data_dir / "scans" / scan_id
    if target.exists():
        raise ConfigError("--out", [f"--out: {target} already exists; choose a new directory"])
    bar = _progress(args)
    with open_rig(config) as the_rig:
        path, result = scan_to_directory(the_rig, target, scan_id, keep_frames=config.scan.save_frames, progress=bar)
    summary = {
        "scan_id": scan_id,
        "path": str(path),
        "codec": result.codec,
        "points": len(result.cloud),
        "frames": result.frames_projected,
        "timings_ms": {k: round(v, 1) for k, v in result.timings_ms.items()},
    }
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(
            f"scan {scan_id}: {len(result.cloud)} points with {result.codec} "
            f"({result.frames_projected} patterns) -> {path}/cloud.ply"
        )
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    config = _load(args)
    if args.scene:
        config = _scene_override(config, args.scene)
    if config.simulation is None:
        raise ConfigError(str(args.config), ["simulation: eval needs a simulated rig"])
    with open_rig(config) as the_rig:
        result = run_scan(the_rig, progress=_progress(args))
        pair = result.pairs[0]
        if result.merged_index is not None:  # several pairs: the merged cloud, and each pair beside it
            merged = evaluate_merge(the_rig, result)
            metrics = {**merged["merged"], "pairs": merged["pairs"], "overlap_cue": merged["overlap_cue"]}
            metrics["merge"] = result.merge
        else:
            metrics = evaluate_on_bench(the_rig, pair)
    scene = config.simulation.scene
    report = {
        "codec": result.codec,
        "scene": (getattr(scene, "path", None) and Path(str(scene.path)).name) or scene.kind,
        "frames": result.frames_projected,
        "bytes_captured": result.bytes_captured,
        **metrics,
        "capture_ms": round(result.timings_ms["capture_ms"], 1),
        "decode_ms": round(result.timings_ms["decode_ms"], 1),
        "triangulate_ms": round(result.timings_ms["triangulate_ms"], 1),
        "pointset_ms": round(result.timings_ms["pointset_ms"], 1),
    }
    if result.merged_index is None:
        report["counts"] = pair.counts
    if args.json:
        print(json.dumps(report, allow_nan=False))
        return 0
    nested = {k: v for k, v in report.items() if isinstance(v, dict)}
    flat = {k: v for k, v in report.items() if k not in nested}
    width = max(len(k) for k in flat)
    for key, value in flat.items():
        shown = f"{value:.4f}" if isinstance(value, float) else str(value)
        print(f"{key:<{width}}  {shown}")
    for key, value in nested.items():
        if key not in ("pairs", "overlap_cue", "merge"):
            print(f"{key:<{width}}  {json.dumps(value)}")
    if "pairs" in nested:  # several pairs: each beside the merged cloud, on the same surface
        print(f"\n{'pair':<40} {'points':>8} {'rms mm':>8} {'merged here':>11} {'complete':>9}")
        for name, p in nested["pairs"].items():
            here = p["merged_rms_mm_here"]
            print(
                f"{name:<40} {p['points']:>8} {p['rms_mm']:>8.4f} "
                f"{'-' if here is None else f'{here:.4f}':>11} {p['completeness']:>9.1%}"
            )
        for camera, cue in nested.get("overlap_cue", {}).items():
            print(f"overlap cue, {camera}: precision {cue['precision']:.3f}, recall {cue['recall']:.3f}")
        merge = nested.get("merge") or {}
        if merge:
            print(
                f"merge: {merge['points_in']} -> {merge['points_out']} points "
                f"({merge['redundant_removed']} redundant, {merge['thinned_removed']} thinned)"
            )
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    if args.views is not None and not 3 <= args.views <= 200:
        raise ConfigError("--views", [f"--views: {args.views} is outside 3..200"])
    out = args.out if args.out is not None else config.output.data_dir / "calibration"
    if args.what == "response":
        with open_rig(config) as the_rig:
            document = calibrate_response(the_rig, out)
        if args.json:
            print(json.dumps({"path": str(out / RESPONSE_NAME), **document}, allow_nan=False))
        else:
            for name, p in document["projectors"].items():
                print(f"{name}: response fits gamma {p['gamma']:.3f} -> {out / RESPONSE_NAME}")
        return 0
    with open_rig(config) as the_rig:
        outcome = calibrate(the_rig, args.what, out, args.views, args.images, args.save_views)
    summary = {"path": str(outcome.folder), "sha256": outcome.sha256, "views": outcome.views, **outcome.report}
    if args.json:
        print(json.dumps(summary, allow_nan=False))
        return 0
    print(f"calibration {outcome.sha256} from {outcome.views} views -> {outcome.folder}/calibration.json")
    for name, d in outcome.report["devices"].items():
        stereo = f", stereo {d['stereo_rms_px']:.3f} px" if d["stereo_rms_px"] is not None else ""
        rejected = f", rejected views {d['rejected_views']}" if d["rejected_views"] else ""
        print(
            f"  {name} ({d['kind']}): rms {d['rms_px']:.3f} px{stereo}, {len(d['views_used'])} views, "
            f"coverage {d['coverage']:.0%}{rejected}"
        )
    for warning in outcome.report["warnings"]:
        print(f"  warning: {warning}")
    return 0


def cmd_doctor(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    problems = check(config)
    report: dict[str, Any] = {"config": str(args.config or "config/sim.yaml"), "problems": problems}
    if args.latency and not problems:
        with open_rig(config) as the_rig:
            values = {p.name: measure_latency(the_rig, i) for i, p in enumerate(config.projectors)}
        report["latency_s"] = {k: round(v, 4) for k, v in values.items()}
        report["latency_file"] = str(store_latencies(config.output.data_dir, values))
    if args.json:
        print(json.dumps(report, allow_nan=False))
    else:
        for p in problems:
            print(f"{p['device']}: {p['problem']}")
        for name, value in report.get("latency_s", {}).items():
            print(
                f"{name}: display-to-capture latency {value * 1000:.1f} ms (stored in {report['latency_file']}; "
                f"set latency_s: measured)"
            )
        if not problems:
            print("no problems found")
    return 1 if problems else 0


def cmd_plan(args: argparse.Namespace) -> int:
    from rig.assembly.simulated import build_scene
    from rig.plan import confirm_on_bench, plan_views

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
        config = _scene_override(config, args.scene)
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
    import numpy as np
    import yaml

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


def cmd_serve(args: argparse.Namespace) -> int:
    import logging

    from rig.daemon.server import load_api_key, serve  # the web stack only for the daemon

    if not 0 <= args.port <= 65535:
        raise ConfigError("--port", [f"--port: {args.port} is outside 0..65535"])
    config = load_config(args.config)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    key = load_api_key(args.api_key_file, config.output.data_dir)
    return serve(config, args.host, args.port, key)


def cmd_devices(args: argparse.Namespace) -> int:
    found = inventory()
    if args.json:
        print(json.dumps(found, allow_nan=False))
    else:
        print("\n".join(describe(found)))
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    handlers = {
        "scan": cmd_scan,
        "eval": cmd_eval,
        "calibrate": cmd_calibrate,
        "devices": cmd_devices,
        "doctor": cmd_doctor,
        "serve": cmd_serve,
        "plan": cmd_plan,
    }
    handler = handlers[args.command]
    try:
        return handler(args)
    except ScanError as exc:
        print(f"slrig: scan failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except DeviceError as exc:
        print(f"slrig: device error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except SlrigError as exc:
        print(f"slrig: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("slrig: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
