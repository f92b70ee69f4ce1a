"""`slrig scan` and `slrig eval`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rig.assembly import open_rig
from rig.cli.common import load, progress_bar, scene_override
from rig.config import RigConfig
from rig.errors import ConfigError, UsageError
from rig.evaluate import evaluate_merge, evaluate_on_bench, pattern_economy
from rig.pipeline import ScanResult, scan_with_exposure
from rig.plan import RingPlan
from rig.service import adaptive_scan_to_directory, scan_to_directory
from rig.store import new_scan_id


def cmd_scan(args: argparse.Namespace) -> int:
    config = load(args)
    scan_id = new_scan_id()
    target = args.out if args.out is not None else config.output.data_dir / "scans" / scan_id
    if target.exists():
        raise UsageError(f"--out: {target} already exists; choose a new directory")
    bar = progress_bar(args)
    # Callers that build their own Namespace (the daemon's tests, scripts) may leave these out.
    piloted, tolerance = getattr(args, "adaptive", False), getattr(args, "tolerance_mm", None)
    quantile = getattr(args, "tolerance_quantile", None)
    plan_file, save_plan = getattr(args, "plan", None), getattr(args, "save_plan", None)
    if not piloted and (tolerance is not None or quantile is not None or save_plan is not None):
        raise ConfigError(
            "--adaptive", ["--tolerance-mm, --tolerance-quantile and --save-plan plan rings: add --adaptive"]
        )
    plan = RingPlan.load(plan_file) if plan_file is not None else None
    keep = config.scan.save_frames or getattr(args, "save_frames", False)
    with open_rig(config) as the_rig:
        if piloted or plan is not None:
            path, result, plan = adaptive_scan_to_directory(
                the_rig, target, scan_id, tolerance, plan, keep, bar, quantile
            )
            if save_plan is not None:
                plan.save(save_plan)
        else:
            path, result = scan_to_directory(the_rig, target, scan_id, keep_frames=keep, progress=bar)
    summary = {
        "scan_id": scan_id,
        "path": str(path),
        "codec": result.codec,
        "points": len(result.cloud),
        "frames": result.frames_projected,
        "timings_ms": {k: round(v, 1) for k, v in result.timings_ms.items()},
    }
    if result.adaptive is not None:
        summary["adaptive"] = {k: v for k, v in result.adaptive.items() if k != "plan"}
    if result.exposure is not None:
        summary["exposure"] = {k: v for k, v in result.exposure.items() if k != "looks"}
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(
            f"scan {scan_id}: {len(result.cloud)} points with {result.codec} "
            f"({result.frames_projected} patterns) -> {path}/cloud.ply"
        )
        if plan is not None:
            print(f"  {plan.rings} planned rings for {plan.tolerance_mm:g} mm; the plan is in the manifest")
            _say_check(result.adaptive or {}, plan.tolerance_mm)
        if keep:
            print(f"  frames kept in {path}/frames: reprocess them with `slrig reconstruct {path}`")
    return 0


def _say_check(adaptive: dict[str, Any], tolerance: float) -> None:
    """One line on what the scan knows of its plan's promise (ScanResult.adaptive's check)."""
    check = adaptive.get("check") or {}
    if check.get("measured_worst_region_p95_mm") is not None:
        verdict = "met" if check["met"] else "NOT met"
        print(f"  measured against the truth: worst region {check['measured_worst_region_p95_mm']:.3g} mm, {verdict}")
    if check.get("same_object_as_pilot") is False:
        print(
            f"  warning: the rings lie {check['pilot_agreement_mm']:.3g} mm from the plan's pilot (more than "
            f"{tolerance:g} mm): a plan made for another object; its tolerance is unverified for this one"
        )


def eval_report(config: RigConfig, result: ScanResult, metrics: dict[str, Any]) -> dict[str, Any]:
    """What `slrig eval` prints: the scan, its accuracy, its times and (rings) its pattern economy."""
    assert config.simulation is not None
    scene = config.simulation.scene
    report = {
        "codec": result.codec,
        "scene": (getattr(scene, "path", None) and Path(str(scene.path)).name) or scene.kind,
        "frames": result.frames_projected,
        "bytes_captured": result.bytes_captured,
        **metrics,
        **{k: round(result.timings_ms[k], 1) for k in ("capture_ms", "decode_ms", "triangulate_ms", "pointset_ms")},
    }
    if "surface_ms" in result.timings_ms:
        report["surface_ms"] = round(result.timings_ms["surface_ms"], 1)
    if result.pairs and result.pairs[0].rings is not None:
        report["economy"] = pattern_economy(result, config)
    if result.merged_index is None:
        report["counts"] = result.pairs[0].counts
    return report


def cmd_eval(args: argparse.Namespace) -> int:
    config = load(args)
    if args.scene:
        config = scene_override(config, args.scene)
    if not config.simulated:
        raise ConfigError(str(args.config), ["simulation: eval needs a simulated rig"])
    with open_rig(config) as the_rig:
        result = scan_with_exposure(the_rig, progress=progress_bar(args))
        pair = result.pairs[0]
        if result.merged_index is not None:  # several pairs: the merged cloud, and each pair beside it
            merged = evaluate_merge(the_rig, result)
            metrics = {**merged["merged"], "pairs": merged["pairs"], "overlap_cue": merged["overlap_cue"]}
            metrics["merge"] = result.merge
        else:
            metrics = evaluate_on_bench(the_rig, pair)
    report = eval_report(config, result, metrics)
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
