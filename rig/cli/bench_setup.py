"""`slrig calibrate`, `slrig doctor` and `slrig devices`: setting a bench up."""

from __future__ import annotations

import argparse
import json
from typing import Any

from rig.assembly import open_rig
from rig.calibrate import RESPONSE_NAME, calibrate, calibrate_described, calibrate_response, calibration_overrides
from rig.cli.common import progress_bar
from rig.config import load_config
from rig.doctor import check, describe, machine_inventory, measure_latency, store_latencies
from rig.errors import ConfigError


def cmd_calibrate(args: argparse.Namespace) -> int:
    models = (getattr(args, "camera_model", None), getattr(args, "projector_model", None))
    config = calibration_overrides(
        load_config(args.config), args.board, args.model, device_models=models, world=getattr(args, "world", None)
    )
    if args.views is not None and not 3 <= args.views <= 200:
        raise ConfigError("--views", [f"--views: {args.views} is outside 3..200"])
    if args.patterns is not None and (args.images is None or args.what not in ("camera", "rig", "projector")):
        problem = "--patterns: give the captures' folder with --images (camera, projector or rig)"
        raise ConfigError("--patterns", [problem])
    out = args.out if args.out is not None else config.output.data_dir / "calibration"
    bar = progress_bar(args)
    if args.what == "response":
        with open_rig(config) as the_rig:
            document = calibrate_response(the_rig, out)
        if args.json:
            print(json.dumps({"path": str(out / RESPONSE_NAME), **document}, allow_nan=False))
        else:
            for name, p in document["projectors"].items():
                print(f"{name}: response fits gamma {p['gamma']:.3f} -> {out / RESPONSE_NAME}")
        return 0
    if args.patterns is not None:
        outcome = calibrate_described(
            config, args.images, args.patterns, out, args.what, args.view_glob, args.board_image, bar
        )
    else:
        with open_rig(config, with_devices=args.images is None) as the_rig:  # views from files: no device
            outcome = calibrate(the_rig, args.what, out, args.views, args.images, args.save_views, progress=bar)
    summary = {"path": str(outcome.folder), "sha256": outcome.sha256, "views": outcome.views, **outcome.report}
    if args.json:
        print(json.dumps(summary, allow_nan=False))
        return 0
    print(f"calibration {outcome.sha256} from {outcome.views} views -> {outcome.folder}/calibration.json")
    for device in outcome.devices:
        d = outcome.report["devices"][device.name]
        stereo = f", stereo {d['stereo_rms_px']:.3f} px" if d["stereo_rms_px"] is not None else ""
        rejected = f", rejected views {d['rejected_views']}" if d["rejected_views"] else ""
        print(
            f"  {device.name} ({d['kind']}): rms {d['rms_px']:.3f} px{stereo}, {len(d['views_used'])} views, "
            f"coverage {d['coverage']:.0%}{rejected}"
        )
        K = device.K
        print(
            f"    model {device.model}: f {K[0, 0]:.1f} {K[1, 1]:.1f} (+-{device.std.get('fy', 0.0):.1f}), "
            f"centre {K[0, 2]:.1f} {K[1, 2]:.1f}, k1 {device.dist[0]:.4f}"
        )
    for pair, ruler in outcome.report["board_check"].items():
        print(
            f"  board check {pair}: squares {ruler['square_error_pct']:+.2f} % of {ruler['square']:g} (worst view "
            f"{ruler['worst_view_square_error_pct']:+.2f} %), corners {ruler['plane_rms']:.3f} rms off their plane"
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


def cmd_devices(args: argparse.Namespace) -> int:
    found = machine_inventory()
    if args.json:
        print(json.dumps(found, allow_nan=False))
    else:
        print("\n".join(describe(found)))
    return 0
