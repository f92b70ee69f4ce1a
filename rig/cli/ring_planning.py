"""`slrig plan rings` and the ring plan of `slrig scan --adaptive / --plan`: the fewest rings a
surface needs, from a pilot scan (run here on the simulated bench, or a stored scan directory)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from rig.assembly import open_rig
from rig.cli.common import progress_bar, scene_override
from rig.config import config_from_dict, load_config
from rig.errors import PlanError, StoreError
from rig.plan import PilotView, RingPlan, plan_rings, rehearsal_progress
from rig.progress import ProgressCallback, ProgressTracker
from rig.service import plan_from_pilot
from rig.store import read_cloud_ply


def cmd_plan_rings(args: argparse.Namespace) -> int:
    if args.source is not None and args.scene is not None:
        raise PlanError("give --from SCAN_DIR or --scene NAME, not both")
    bar = progress_bar(args)
    quantile = getattr(args, "tolerance_quantile", None)
    if args.source is not None:
        plan = plan_from_scan_dirs(args.source, args.tolerance_mm, bar, quantile)
    else:
        config = load_config(args.config)
        if args.scene:
            config = scene_override(config, args.scene)
        if not config.simulated:
            raise PlanError("--scene: a real rig plans from a scan it made: --from SCAN_DIR")
        with open_rig(config) as the_rig:
            plan = plan_from_pilot(the_rig, args.tolerance_mm, bar, quantile)
    if args.out is not None:
        plan.save(args.out)
    print_plan(plan, args.json)
    return 0


def plan_from_scan_dirs(
    folders: list[Path],
    tolerance_mm: float | None,
    progress: ProgressCallback | None = None,
    quantile: float | None = None,
) -> RingPlan:
    """The plan for the surfaces stored scans saw (their cloud.ply, their rigs from their manifests):
    one ring set that meets the tolerance on every one of them (a plan for a kind of object). The
    first scan's rig supplies the plan's settings; every scan's projector must match its size."""
    views: list[PilotView] = []
    pilots: list[dict[str, Any]] = []
    config = None
    for folder in folders:
        manifest, found = _scan_views(folder)
        config = config or config_from_dict(manifest["config"], f"scan {manifest.get('scan_id', folder.name)}")
        if views and (found[0].projector.width, found[0].projector.height) != (
            views[0].projector.width,
            views[0].projector.height,
        ):
            raise PlanError(f"--from: {folder} was scanned by another projector size than {folders[0]}")
        views += found
        pilot = {"codec": manifest["codec"]["name"], "scan_id": manifest.get("scan_id")}
        pilots.append(pilot | {k: manifest["economy"][k] for k in ("frames_projected", "bytes_captured")})
    assert config is not None
    about: dict[str, Any] = dict(pilots[0]) if len(pilots) == 1 else {"codec": pilots[0]["codec"], "scans": pilots}
    if len(pilots) > 1:  # the pilots' cost, counted once for the kind of object
        about.update({k: sum(p[k] for p in pilots) for k in ("frames_projected", "bytes_captured")})
    tracker = ProgressTracker(progress)
    interpolant = config.scan.surface.interpolant
    found_plan = plan_rings(
        views, config.scan.adaptive, tolerance_mm, about, interpolant, rehearsal_progress(tracker, 0), quantile
    )
    tracker.report("plan", 1.0)
    return found_plan


def _scan_views(folder: Path) -> tuple[dict[str, Any], list[PilotView]]:
    """A stored scan's manifest and its points as pilot views, one per pair, on its own rig."""
    try:
        manifest = json.loads((folder / "manifest.json").read_text())
        cloud = read_cloud_ply((folder / manifest["files"]["cloud"]).read_bytes(), str(folder / "cloud.ply"))
    except (OSError, ValueError, KeyError) as exc:
        raise StoreError(f"--from: {folder} is not a readable scan directory ({exc})") from None
    config = config_from_dict(manifest["config"], f"scan {manifest.get('scan_id', folder.name)}")
    projectors = [p.name for p in config.projectors]
    cameras = [c.name for c in config.cameras]
    views = []
    with open_rig(config, with_devices=False) as geometry:
        for source, pair in enumerate(manifest["pairs"]):
            p, c = projectors.index(pair["projector"]), cameras.index(pair["camera"])
            points = cloud.points[cloud.source == source]
            camera = geometry.camera_models[c]  # the points go back on its pixels for the rehearsal
            views.append(PilotView(points, geometry.projector_models[p], camera.center, camera))
    return manifest, views


def print_plan(plan: RingPlan, as_json: bool) -> None:
    if as_json:
        report = plan.as_dict()
        report.pop("profile")  # as the pilot's signatures: the plan file (--out) keeps them
        report["pilot"] = {k: v for k, v in report["pilot"].items() if k != "signatures"}
        print(json.dumps(report, allow_nan=False))
        return
    criteria = plan.criteria
    uniform, frequency = criteria["sagitta_uniform"], criteria["curvature_frequency"]
    uneven = criteria.get("rms_nonuniform")
    if uneven is not None:
        even = criteria["rms_uniform"]
        rehearsed, other, kind = (even, uneven, "uneven") if even.get("chosen") else (uneven, even, "evenly spaced")
        spacing = " (evenly spaced: no uneven set needs fewer)" if even.get("chosen") else ""
        share = f"{100 * plan.quantile:g} %"
        print(
            f"{plan.rings} rings{spacing} for {plan.tolerance_mm:g} mm on {share} of every surface region: "
            f"rehearsed on the pilot {rehearsed['worst_region_mm']:g} mm on the worst region "
            f"({rehearsed['rms_mm']:g} mm rms), {100 * rehearsed['covered']:.1f} % covered"
        )
        same = "" if other["met"] else ", not met"
        print(f"  {kind} rings for the same: {other['rings']} (rehearsed {other['worst_region_mm']:g} mm{same})")
    else:
        print(f"{plan.rings} rings for {plan.tolerance_mm:g} mm between them (non-uniform radii, sagitta bound)")
    print(f"  sagitta bound (worst point, linear): {uniform['rings']} even rings ({uniform['spacing_px']:g} px apart)")
    print(
        f"  curvature-frequency criterion: N_min = ceil({frequency['dense_rings']} x {frequency['f_s']:g}) = "
        f"{frequency['rings']} (f_max {frequency['f_max_per_mm']:g} per mm)"
    )
    spacing = np.diff(plan.radii_px)
    radii = f"{plan.radii_px[0]:.1f} .. {plan.radii_px[-1]:.1f} px"
    print(f"  radii {radii}, spacing {spacing.min():.1f} .. {spacing.max():.1f} px")
