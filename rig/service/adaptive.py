"""An adaptive scan (dissertation ch.4 as a workflow): a dense pilot scan, a ring plan from its
curvature, then the planned sparse ring scan. With a plan given (a file a lab keeps per kind of
object), the pilot is skipped. The pilot and the ring scan both take the exposure, HDR and adaptive
projection that `scan.exposure` asks for (rig.pipeline.hdr.scan_with_exposure)."""

from __future__ import annotations

import dataclasses
from typing import Any

from rig.config import RigConfig, config_from_dict
from rig.errors import ConfigError, PlanError
from rig.evaluate import held_out_error
from rig.opened_rig import Rig
from rig.pipeline import ScanResult, scan_with_exposure
from rig.plan import RingPlan, disagreement, pilot_views, plan_rings, rehearsal_progress
from rig.progress import ProgressCallback, ProgressTracker
from rig.store import projector_view


def plan_from_pilot(
    the_rig: Rig, tolerance_mm: float | None, progress: ProgressCallback | None = None, quantile: float | None = None
) -> RingPlan:
    """Scan with the pilot codec (scan.adaptive.pilot_codec) and plan the rings from what it saw."""
    return pilot_and_plan(the_rig, tolerance_mm, progress, quantile)[1]


def pilot_and_plan(
    the_rig: Rig, tolerance_mm: float | None, progress: ProgressCallback | None = None, quantile: float | None = None
) -> tuple[ScanResult, RingPlan]:
    """plan_from_pilot, and the pilot scan itself."""
    settings = the_rig.config.scan.adaptive
    tracker = ProgressTracker(progress)
    pilot = scan_with_exposure(the_rig, settings.pilot_codec, progress=tracker.part(0.0, 0.5, "pilot "))
    tracker.report("plan", 0.5)
    views = pilot_views(pilot, the_rig.camera_models, the_rig.projector_models)
    about = {"codec": pilot.codec, "frames_projected": pilot.frames_projected, "bytes_captured": pilot.bytes_captured}
    interpolant = the_rig.config.scan.surface.interpolant
    found = plan_rings(views, settings, tolerance_mm, about, interpolant, rehearsal_progress(tracker, 0.5), quantile)
    return pilot, found


def check_scan_request(config: RigConfig, request: dict[str, Any]) -> None:
    """Refuse (PlanError, naming the field) what a scan request's schema cannot: adaptive and plan
    together, tolerance_mm without adaptive, another codec beside either, a plan that is not one or
    does not fit this rig's projectors."""
    adaptive, plan = bool(request.get("adaptive")), request.get("plan")
    if plan is not None and adaptive:
        raise PlanError("plan: give a plan or adaptive: true, not both")
    for name in ("tolerance_mm", "tolerance_quantile"):
        if request.get(name) is not None and not adaptive:
            raise PlanError(f"{name}: only an adaptive scan plans to a tolerance (adaptive: true)")
    codec = request.get("codec")
    if (adaptive or plan is not None) and codec not in (None, "rings"):
        raise PlanError(f"codec: an adaptive or planned scan projects rings, not {codec}")
    if plan is not None:
        planned_config(config, RingPlan.from_dict(plan, "plan"))
    hdr = request.get("hdr", config.scan.exposure.hdr)
    if isinstance(hdr, list) and not 2 <= len(hdr) <= 10:
        raise PlanError(f"hdr: 2 to 10 exposures, got {len(hdr)}")


def planned_config(config: RigConfig, plan: RingPlan) -> RigConfig:
    """The config scanning the plan's rings; PlanError where they do not fit the rig's projectors."""
    for projector in config.projectors:
        width, height = projector.resolution
        cx, cy = plan.center_px
        if not (-0.5 <= cx < width - 0.5 and -0.5 <= cy < height - 0.5):
            raise PlanError(
                f"center_px: ({cx:g}, {cy:g}) lies outside {projector.name}'s {width}x{height} image: "
                "a plan for another projector"
            )
    data = config.model_dump(mode="json")
    data["scan"]["codec"] = "rings"
    rings = data["scan"]["rings"]
    rings.update(radii_px=plan.radii_px, center_px=list(plan.center_px), rings=plan.rings)
    try:
        return config_from_dict(data, "the ring plan")
    except ConfigError as exc:
        raise PlanError(f"the plan's rings do not fit this rig: {'; '.join(exc.problems)}") from None


def with_plan(the_rig: Rig, plan: RingPlan) -> Rig:
    """The same rig (devices and geometry shared) scanning the plan's rings."""
    return dataclasses.replace(the_rig, config=planned_config(the_rig.config, plan))


def adaptive_scan(
    the_rig: Rig,
    tolerance_mm: float | None = None,
    plan: RingPlan | None = None,
    keep_frames: bool = False,
    progress: ProgressCallback | None = None,
    quantile: float | None = None,
) -> tuple[ScanResult, RingPlan, Rig]:
    """Pilot (unless `plan` is given), plan, and the planned ring scan; the result records the plan,
    what the scan cost beside the pilot and how its ring points agree with the plan's pilot
    (ScanResult.adaptive). Also returns the rig as it scanned the plan (with_plan), whose config the
    stored scan records."""
    pilot = None
    tracker = ProgressTracker(progress)
    if plan is None:
        pilot, plan = pilot_and_plan(the_rig, tolerance_mm, tracker.part(0.0, 0.6), quantile)
    sparse = with_plan(the_rig, plan)
    start = 0.0 if pilot is None else 0.6
    result = scan_with_exposure(sparse, "rings", tracker.part(start, 0.92, "rings "), keep_frames)
    result.adaptive = adaptive_record(plan, result, pilot is not None)
    result.adaptive["pilot_agreement_mm"] = pilot_agreement(plan, result, sparse)
    held_out = [e for e in (held_out_error(sparse, pair) for pair in result.pairs) if e is not None]
    result.adaptive["held_out_ring_p95_mm"] = round(max(held_out), 4) if held_out else None
    if pilot is not None:  # the picture the console draws the plan over (projector pixels, as the plan)
        result.images["pilot_projector"] = projector_view(pilot.cloud, the_rig.projector_models[0])
    return result, plan, sparse


def adaptive_record(plan: RingPlan, result: ScanResult, piloted: bool) -> dict[str, Any]:
    """The plan, and the pattern economy: the ring scan's frames and bytes beside the dense pilot's
    (which this scan paid for only when it ran the pilot, not when it reused a plan)."""
    pilot = plan.pilot
    return {
        "plan": plan.as_dict(),
        "rings": plan.rings,
        "tolerance_mm": plan.tolerance_mm,
        "tolerance_quantile": plan.quantile,
        "pilot_scanned": piloted,
        "economy": {
            "ring_frames": result.frames_projected,
            "ring_bytes": result.bytes_captured,
            "dense_codec": pilot.get("codec"),
            "dense_frames": pilot.get("frames_projected"),
            "dense_bytes": pilot.get("bytes_captured"),
        },
    }


def pilot_agreement(plan: RingPlan, result: ScanResult, the_rig: Rig) -> float | None:
    """How far (mm: per ring the median over its angles, the worst ring) the scan's ring points lie
    from where the plan's pilot had its surface on the same rings (rig.plan.signature.disagreement):
    the nearest of the plan's pilots, the worst of the scan's pairs. None where the plan keeps no
    pilot or too few rings meet."""
    signatures = plan.pilot.get("signatures") or []
    worst: float | None = None
    for pair in result.pairs:
        if pair.rings is None:
            continue
        keep = pair.rings.kept
        points, ring, projector = (
            pair.rings.points[keep],
            pair.rings.ring[keep],
            the_rig.projector_models[pair.projector],
        )
        found = [disagreement(s, points, ring, projector, plan.center_px) for s in signatures if isinstance(s, dict)]
        nearest = min((f for f in found if f is not None), default=None)
        if nearest is not None:
            worst = nearest if worst is None else max(worst, nearest)
    return None if worst is None else round(worst, 4)


def plan_check(adaptive: dict[str, Any], metrics: dict[str, Any]) -> dict[str, Any]:
    """What the plan promised and what this scan knows of it, strongest first. On a simulated rig
    the surface's worst region by area is measured against the truth (rig.evaluate.regions):
    `measured`. On any rig, the surface of every other ring misses the rings left out by at most
    the tolerance (rig.pipeline.holdout, an upper bound at twice the spacing): `bounded`. A plan
    rehearsed on this very object (its own pilot, or a plan file whose pilot the rings agree with to
    within the tolerance): `rehearsed`. Otherwise, a plan made for another object is flagged and its
    tolerance is `unverified` here, whatever its file claims."""
    worst = [
        m["surface_worst_region_p95_mm"]
        for m in metrics.values()
        if isinstance(m, dict) and m.get("surface_worst_region_p95_mm") is not None
    ]
    tolerance = adaptive["tolerance_mm"]
    measured = max(worst) if worst else None
    agreement = adaptive.get("pilot_agreement_mm")
    same_object = None if agreement is None else bool(agreement <= tolerance)
    rehearsed = bool(adaptive["pilot_scanned"] or same_object)
    held_out = adaptive.get("held_out_ring_p95_mm")
    bounded = held_out is not None and held_out <= tolerance
    status = (
        "measured" if measured is not None else "bounded" if bounded else "rehearsed" if rehearsed else "unverified"
    )
    return {
        "promised_mm": tolerance,
        "quantile": adaptive.get("tolerance_quantile", 0.95),
        "rehearsed_on_this_object": rehearsed,
        "pilot_agreement_mm": agreement,
        "same_object_as_pilot": same_object,
        "held_out_ring_p95_mm": held_out,
        "measured_worst_region_p95_mm": measured,
        "met": None if measured is None else bool(measured <= tolerance),
        "verified": measured is not None,
        "tolerance": status,
    }
