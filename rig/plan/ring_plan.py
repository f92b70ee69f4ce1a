"""A ring plan: planned from a pilot (rig.plan.ring_spacing), kept in a file that later scans reuse.

The file is JSON (YAML is read too): the radii to project, both criteria, the spacing profile they
came from, and what the pilot was. A scan takes a plan's radii as its rings codec's `radii_px`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from rig.config import RingPlanSettings
from rig.errors import PlanError
from rig.geometry import CameraModel
from rig.patterns import EDGE_RAMP_PX, RingsParams, farthest_corner_px
from rig.pipeline import Interpolant, ScanResult
from rig.plan.rehearsal import Rehearsal, noise_mm, organised, pilot_surface
from rig.plan.ring_spacing import (
    Demand,
    PilotView,
    demand,
    frequency_criterion,
    pilot_curvature,
    place_rings,
    spacing_profile,
    uniform_rings,
)
from rig.plan.search import Rehearser, nonuniform_rings, rms_shape, uniform_count
from rig.plan.signature import pilot_signature

PLAN_FORMAT = "slrig-ring-plan/1"


@dataclass(frozen=True)
class RingPlan:
    """The rings to project (`radii_px` about `center_px`, one set for every projector) and why."""

    tolerance_mm: float
    center_px: tuple[float, float]
    radii_px: list[float]
    criteria: dict[str, dict[str, Any]]
    profile: dict[str, list[float]]  # radius bins (px) and the spacing each allows (px)
    pilot: dict[str, Any] = field(default_factory=dict)
    quantile: float = 0.95  # the share of every region's area the tolerance holds for

    @property
    def rings(self) -> int:
        return len(self.radii_px)

    def as_dict(self) -> dict[str, Any]:
        return {
            "format": PLAN_FORMAT,
            "tolerance_mm": self.tolerance_mm,
            "tolerance_quantile": self.quantile,
            "center_px": list(self.center_px),
            "rings": self.rings,
            "radii_px": [round(r, 2) for r in self.radii_px],
            "criteria": self.criteria,
            "pilot": self.pilot,
            "profile": self.profile,
        }

    def save(self, path: Path) -> None:
        Path(path).write_text(json.dumps(self.as_dict(), indent=1, allow_nan=False) + "\n")

    @staticmethod
    def from_dict(data: Any, source: str = "plan") -> RingPlan:
        """A plan read back; raises PlanError naming the field that is missing or wrong (numbers
        must be JSON numbers, not strings or booleans; criteria, profile and pilot objects)."""
        if not isinstance(data, dict) or data.get("format") != PLAN_FORMAT:
            raise PlanError(f"{source}: not a ring plan (format must be {PLAN_FORMAT!r})")
        try:
            radii = [_number(r, "radii_px") for r in _array(data.get("radii_px"), "radii_px")]
            center_px = _array(data.get("center_px"), "center_px")
            if len(center_px) != 2:
                raise ValueError(f"center_px: {len(center_px)} numbers, not 2")
            center = (_number(center_px[0], "center_px"), _number(center_px[1], "center_px"))
            tolerance = _number(data.get("tolerance_mm"), "tolerance_mm")
            quantile = _number(data.get("tolerance_quantile", 0.95), "tolerance_quantile")
            parts = {name: _object(data.get(name, {}), name) for name in ("criteria", "profile", "pilot")}
        except ValueError as exc:
            raise PlanError(f"{source}: {exc}") from None
        try:  # the rings codec's own checks on radii and centre
            RingsParams(radii_px=radii, center_px=center)
        except ValidationError as exc:
            problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or 'radii_px'}: {e['msg']}" for e in exc.errors())
            raise PlanError(f"{source}: {problems}") from None
        return RingPlan(tolerance, center, radii, parts["criteria"], parts["profile"], parts["pilot"], quantile)

    @staticmethod
    def load(path: Path) -> RingPlan:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise PlanError(f"cannot read plan {path}: {exc.strerror or exc}") from None
        try:
            data = json.loads(text) if text.lstrip().startswith("{") else yaml.safe_load(text)
        except (json.JSONDecodeError, yaml.YAMLError) as exc:
            raise PlanError(f"plan {path} is not JSON or YAML: {exc}") from None
        return RingPlan.from_dict(data, str(path))


def plan_rings(
    views: list[PilotView],
    settings: RingPlanSettings,
    tolerance_mm: float | None = None,
    pilot: dict[str, Any] | None = None,
    method: Interpolant = "quadratic",
    on_rehearsal: Callable[[Rehearsal], None] | None = None,
    quantile: float | None = None,
) -> RingPlan:
    """The plan for the pilot's views (one per projector and camera, of one object or several of a
    kind): one set of radii for every projector. With the views' cameras known, the fewest
    non-uniform rings whose surface (by the interpolant `method`) rehearses within the tolerance on
    `quantile` of the area of every region, covering the surface (rig.plan.search), or evenly spaced
    ones where fewer of those do; PlanError, saying what would, where no ring set can. Without the
    cameras, the sagitta bound's rings, under the strictest demand any view makes at each radius.
    `on_rehearsal` hears of each ring set rehearsed (a search takes tens of them)."""
    tolerance = settings.tolerance_mm if tolerance_mm is None else tolerance_mm
    if not np.isfinite(tolerance) or tolerance <= 0:
        raise PlanError(f"tolerance_mm: must be a positive number of millimetres, got {tolerance}")
    quantile = settings.tolerance_quantile if quantile is None else quantile
    if not 0.5 <= quantile <= 1.0:
        raise PlanError(f"tolerance_quantile: must lie between 0.5 and 1, got {quantile}")
    views = [v for v in views if len(v.points)]
    if not views:
        raise PlanError("pilot: the pilot scan has no points")
    projector = views[0].projector
    center = ((projector.width - 1) / 2, (projector.height - 1) / 2)
    demands: list[Demand] = []
    for view in views:
        curvature = pilot_curvature(view, settings)
        demands.append(demand(view, curvature, tolerance, center, settings.max_spacing_px))
    if sum(len(d.radius_px) for d in demands) < 10:
        raise PlanError("pilot: the rings do not reach the scanned surface (no lit, smooth point inside the projector)")
    edges, profile = spacing_profile(demands, settings)
    # the farthest a ring can be and still show its edge whole, in a frame corner
    last = farthest_corner_px(projector.width, projector.height, center) - EDGE_RAMP_PX
    radii = place_rings(edges, profile, settings.bin_px, last)
    count, spacing = uniform_rings(edges, profile, settings.bin_px)
    rate = float(np.median(np.concatenate([d.px_per_mm for d in demands])))
    criteria: dict[str, dict[str, Any]] = {
        "sagitta_nonuniform": {"rings": len(radii)},
        "sagitta_uniform": {"rings": count, "spacing_px": round(spacing, 2)},
        "curvature_frequency": frequency_criterion(views, center, settings, edges, rate),
    }
    step = settings.rehearsal_step_px
    pilots = [pilot_surface(_grid(v), v.camera, v.projector, center, step) for v in views if v.camera is not None]
    signatures: list[dict[str, Any]] = []
    if pilots:
        noise = float(np.median([noise_mm(p) for p in pilots]))
        trial = Rehearser(pilots, center, method, noise, quantile, on_rehearsal)
        radii = _rehearsed(trial, demands, edges, settings, tolerance, criteria, last)
        signatures = [pilot_signature(p, np.asarray(radii), center) for p in pilots]
    pilot = _pilot_record(pilot, views, demands, edges, settings.bin_px, signatures)
    profile_out = {
        "radius_px": [round(float(e), 1) for e in edges],
        "spacing_px": [round(float(p), 2) for p in profile],
    }
    return RingPlan(tolerance, center, radii, criteria, profile_out, pilot, quantile)


def _pilot_record(
    pilot: dict[str, Any] | None,
    views: list[PilotView],
    demands: list[Demand],
    edges: np.ndarray,
    bin_px: float,
    signatures: list[dict[str, Any]],
) -> dict[str, Any]:
    """What a plan keeps of its pilot: what the caller said, its size, its curvature, the radii it
    spans and (rehearsed plans) its signature per view (rig.plan.signature)."""
    kappa = np.concatenate([d.kappa_across for d in demands])
    return {
        **(pilot or {}),
        "points": int(sum(len(v.points) for v in views)),
        "curvature_samples": len(kappa),
        "kappa_across_p50_p98_per_mm": [round(float(q), 5) for q in np.percentile(kappa, [50, 98])],
        "radius_range_px": [round(float(edges[0]), 1), round(float(edges[-1] + bin_px), 1)],
        **({"signatures": signatures} if signatures else {}),
    }


def _rehearsed(
    trial: Rehearser,
    demands: list[Demand],
    edges: np.ndarray,
    settings: RingPlanSettings,
    tolerance: float,
    criteria: dict[str, dict[str, Any]],
    last_px: float,
) -> list[float]:
    """The fewest rehearsed radii that meet the tolerance: the non-uniform ones, or evenly spaced
    ones where those need fewer (a surface that bends alike everywhere); adds both rehearsed
    criteria to `criteria`, the one chosen marked. No ring lies beyond `last_px`."""
    shape = rms_shape(demands, edges, settings.bin_px)
    target = tolerance * settings.rehearsal_margin
    planned = nonuniform_rings(trial, edges, shape, settings, target, last_px)
    uniform = uniform_count(trial, edges, settings, target)
    inward = np.arange(edges[0] - settings.bin_px, settings.min_radius_px - 1e-9, -settings.bin_px)[::-1]
    if not (planned.met or uniform.met) and len(inward):
        # the rings begin at the surface's innermost radius; the disc inside the first ring is filled
        # across (rig.pipeline.disc_fill) and may err the most: try the rings from the least radius
        edges, shape = np.concatenate([inward, edges]), np.concatenate([np.full(len(inward), shape[0]), shape])
        planned = nonuniform_rings(trial, edges, shape, settings, target, last_px)
        uniform = uniform_count(trial, edges, settings, target)
    even = uniform.met and (not planned.met or len(uniform.radii_px) < len(planned.radii_px))
    for name, found, chosen in (("rms_nonuniform", planned, not even), ("rms_uniform", uniform, even)):
        criteria[name] = {
            **found.rehearsal.as_dict(),
            "met": found.met,
            "interpolant": trial.method,
            "chosen": chosen,
            "tried": _tried(found.tried),  # the predicted error at each ring count the search rehearsed
        }
    criteria["rms_nonuniform"]["pilot_noise_mm"] = round(trial.noise_mm, 4)
    if not (planned.met or uniform.met):
        raise PlanError(refusal(planned.rehearsal, tolerance, trial, settings))
    return uniform.radii_px if even else planned.radii_px


def refusal(densest: Rehearsal, tolerance: float, trial: Rehearser, settings: RingPlanSettings) -> str:
    """Why no ring set meets the tolerance, and what would: from the densest rings rehearsed."""
    share = f"{100 * densest.quantile:g} %"
    target = tolerance * settings.rehearsal_margin
    said = [
        f"tolerance_mm: no ring set keeps {share} of every surface region within {tolerance:g} mm (rehearsed "
        f"within {target:.3g} mm: scan.adaptive.rehearsal_margin) and covers {100 * settings.min_coverage:g} % "
        f"of it: the densest rehearsed ({densest.rings} rings, every {settings.min_spacing_px:g} px at the most) "
        f"reach {densest.worst_region_mm:.3g} mm on the worst region and cover {100 * densest.covered:.1f} %."
    ]
    tolerance = target  # what the rehearsals have to meet
    if trial.noise_mm > 0.5 * tolerance:
        said.append(
            f"The pilot's own noise is {trial.noise_mm:.3g} mm: a finer camera (more pixels on the object) or a "
            "closer stand-off, or a larger tolerance."
        )
    if densest.worst_region_mm > tolerance:
        spacing = settings.min_spacing_px * min(1.0, (tolerance / max(densest.worst_region_mm, 1e-9)) ** 0.5)
        said.append(
            f"More rings: rings about every {max(spacing, 1.0):.2g} px (scan.adaptive.min_spacing_px, now "
            f"{settings.min_spacing_px:g}), where the projector can show them apart."
        )
    if densest.covered < settings.min_coverage:
        said.append(
            "The rings leave depth steps or limbs uncovered: a second view (another camera or projector) or a "
            "dense codec (phase, gray) for this object."
        )
    return " ".join(said)


def _tried(rehearsals: list[Rehearsal]) -> list[dict[str, float | int]]:
    """Each ring count rehearsed once, fewest first: rings, rms_mm, worst_region_mm and covered."""
    by_count = {r.rings: r for r in rehearsals}
    keep = ("rings", "rms_mm", "worst_region_mm", "covered")
    return [{k: v for k, v in by_count[n].as_dict().items() if k in keep} for n in sorted(by_count)]


def _grid(view: PilotView) -> np.ndarray:
    assert view.camera is not None
    return view.grid if view.grid is not None else organised(view.points, view.camera)


def pilot_views(result: ScanResult, cameras: list[CameraModel], projectors: list[CameraModel]) -> list[PilotView]:
    """One view per (projector, camera) pair of a pilot scan."""
    return [
        PilotView(
            pair.points.points,
            projectors[pair.projector],
            cameras[pair.camera].center,
            cameras[pair.camera],
            pair.grid,
        )
        for pair in result.pairs
    ]


def _number(value: Any, name: str) -> float:
    """A finite JSON number as a float; ValueError naming the field otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name}: {value!r} is not a number")
    try:
        number = float(value)
    except OverflowError:
        raise ValueError(f"{name}: {value!r} is too large") from None
    if not math.isfinite(number):
        raise ValueError(f"{name}: {value!r} is not a finite number")
    return number


def _array(value: Any, name: str) -> list[Any]:
    if not isinstance(value, list):
        raise ValueError(f"{name}: must be a list of numbers")
    return value


def _object(value: Any, name: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ValueError(f"{name}: must be an object")
    return dict(value)
