"""The ring planner (dissertation ch.4): Table 1, the sagitta plan, its refusals, its file; curvature
on a noisy simulated scan."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.config import load_config
from rig.config.scan import RingPlanSettings
from rig.errors import PlanError
from rig.evaluate.pairs import evaluate_pair
from rig.geometry.curvature import principal_curvatures
from rig.pipeline.scan import run_scan
from rig.plan.rehearsal import noise_mm, pilot_surface, rehearse, ring_samples
from rig.plan.ring_plan import RingPlan, pilot_views, plan_rings
from rig.plan.ring_spacing import PilotView, _PooledSpectrum, graded, minimum_rings, place_rings, ring_polar
from rig.service.adaptive import with_plan

# Lee & Krim 2017, Table 1: model, N (initial patterns), f_s, N_s (minimum patterns), as published.
TABLE_1 = [
    ("Brian", 147, 0.38, 56),
    ("Eric", 153, 0.40, 62),
    ("Greg", 142, 0.33, 47),
    ("Jeff", 221, 0.49, 109),
    ("Weihong", 271, 0.33, 90),
    ("fvgallary", 89, 0.30, 27),
    ("fvinput", 93, 0.44, 41),
]


@pytest.mark.parametrize(("model", "dense", "rate", "published"), TABLE_1)
def test_table_1_of_the_sampling_paper(model: str, dense: int, rate: float, published: int) -> None:
    assert minimum_rings(dense, rate) == published, model


def test_n_min_rounds_up_not_to_nearest_and_survives_float_noise() -> None:
    assert minimum_rings(153, 0.40) == 62  # 61.2: rounding would give 61
    assert minimum_rings(90, 0.3) == 27  # 0.3 * 90 is 27.000000000000004 in floating point
    with pytest.raises(PlanError):
        minimum_rings(0, 0.5)


def test_the_pooled_spectrum_finds_a_curvature_ripples_frequency() -> None:
    spectrum = _PooledSpectrum(0.5)
    s = np.arange(2000) * 0.5
    spectrum.add(0.02 * np.sin(2 * np.pi * 0.05 * s))  # curvature rippling every 20 mm
    assert abs(spectrum.band_limit(0.95) - 0.05) < 0.01
    flat = _PooledSpectrum(0.5)
    flat.add(np.full(400, 0.02))  # a circle: all its energy at zero frequency
    assert flat.band_limit(0.95) < 0.01


def test_rings_are_placed_greedily_under_the_spacing_each_radius_allows() -> None:
    edges = np.arange(10.0, 400.0, 2.0)
    profile = np.where((edges > 100) & (edges < 150), 8.0, 40.0)
    radii = np.array(place_rings(edges, profile, 2.0))
    assert radii[-1] >= edges[-1]
    for a, b in itertools.pairwise(radii):
        inside = (edges + 2.0 > a) & (edges <= b)
        assert b - a <= profile[inside].min() + 1e-9
    dense = np.diff(radii)[(radii[:-1] > 100) & (radii[:-1] < 140)]
    assert dense.max() <= 8.0 and np.diff(radii).max() > 30.0
    capped = place_rings(edges, profile, 2.0, last_px=355.0)  # a projector whose corners are this near
    assert capped[-1] <= 355.0 and capped == [r for r in radii if r < capped[-1]] + [capped[-1]]
    assert np.diff(capped).min() >= 8.0 - 1e-9


@pytest.fixture(scope="module")
def pilot() -> tuple[list[PilotView], RingPlanSettings]:
    config = load_config()
    with open_rig(config) as rig:
        result = run_scan(rig, "phase")
        return pilot_views(result, rig.camera_models, rig.projector_models), config.scan.adaptive


def test_a_graded_profile_grows_a_gap_by_half_of_itself_at_most() -> None:
    edges = np.arange(10.0, 400.0, 2.0)
    profile = np.where((edges > 100) & (edges < 150), 8.0, 200.0)  # dense over an object, sparse beyond
    smooth = graded(profile, 2.0)
    assert np.all(smooth <= profile) and np.allclose(smooth[(edges > 100) & (edges < 150)], 8.0)
    assert np.abs(np.diff(smooth)).max() <= 0.5 * 2.0 + 1e-9  # 0.5 px per px of radius
    dense = edges[(edges > 100) & (edges < 150)]
    assert smooth[-1] == pytest.approx(8.0 + 0.5 * (edges[-1] - dense[-1]))  # growing away from the object
    assert smooth[0] == pytest.approx(8.0 + 0.5 * (dense[0] - edges[0]))
    radii = np.array(place_rings(edges, smooth, 2.0))
    gaps = np.diff(radii)
    assert np.all(gaps[1:] <= 1.5 * gaps[:-1] + 2.0)  # each gap at most half as wide again (and a bin)


def test_curvature_of_a_noisy_simulated_scan(pilot: tuple[list[PilotView], RingPlanSettings]) -> None:
    view = pilot[0][0]
    c = principal_curvatures(view.points, view.viewpoint, radius_mm=5.0, spacing_mm=2.5)  # as the planner reads it
    centre = np.array([0.0, 0.0, 60.0])  # the default scene: a sphere of radius 60 on the plane
    top = c.valid & (np.linalg.norm(c.points - centre, axis=1) > 55) & (c.points[:, 2] > 100)
    plane = (
        c.valid & (np.hypot(c.points[:, 0], c.points[:, 1]) > 120) & (np.hypot(c.points[:, 0], c.points[:, 1]) < 170)
    )
    assert top.sum() > 50 and plane.sum() > 200
    assert abs(np.median(c.mean[top]) - 1 / 60) < 0.1 / 60
    assert np.percentile(np.abs(c.k1[plane]), 90) < 0.1 / 60


@pytest.fixture(scope="module")
def plans(pilot: tuple[list[PilotView], RingPlanSettings]) -> dict[float, RingPlan]:
    views, settings = pilot
    return {tolerance: plan_rings(views, settings, tolerance) for tolerance in (0.2, 0.5)}


def test_the_plan_crowds_rings_over_the_sphere_and_beats_any_uniform_set(plans: dict[float, RingPlan]) -> None:
    plan = plans[0.2]
    rehearsed = plan.criteria["rms_nonuniform"]
    assert rehearsed["met"] and rehearsed["worst_region_mm"] <= 0.2 and rehearsed["rings"] == plan.rings
    assert rehearsed["covered"] >= 0.95
    uniform = plan.criteria["rms_uniform"]
    assert uniform["met"] and plan.rings <= 0.7 * uniform["rings"]
    assert plan.criteria["sagitta_uniform"]["rings"] > plan.rings
    radii = np.array(plan.radii_px)
    gaps = np.diff(radii)
    sphere = radii[:-1] < 150  # the sphere fills the projector's first 150 px or so
    assert gaps[sphere].mean() < gaps[~sphere].mean()
    frequency = plan.criteria["curvature_frequency"]
    assert frequency["rings"] == minimum_rings(frequency["dense_rings"], frequency["f_s"])
    assert plans[0.5].rings <= plan.rings  # where coverage (keep_coverage) decides, both alike


def test_a_plan_is_the_fewest_rings_either_spacing_rehearsed_within_tolerance(plans: dict[float, RingPlan]) -> None:
    for plan in plans.values():
        uneven, even = plan.criteria["rms_nonuniform"], plan.criteria["rms_uniform"]
        assert uneven["chosen"] != even["chosen"]
        chosen, other = (even, uneven) if even["chosen"] else (uneven, even)
        assert chosen["rings"] == plan.rings and chosen["met"]
        assert not other["met"] or other["rings"] >= plan.rings
        if even["chosen"]:
            assert np.ptp(np.diff(plan.radii_px)) < 1e-6


def test_the_planned_scan_meets_its_tolerance(plans: dict[float, RingPlan]) -> None:
    """The promise by area, on every region: the sphere's p95 as much as the bench's."""
    plan = plans[0.2]
    with open_rig(load_config()) as rig:
        result = run_scan(with_plan(rig, plan), "rings")
        assert rig.truth is not None
        metrics = evaluate_pair(result.pairs[0], rig.truth.ground_truth(0, 0), rig.truth)
    assert metrics["surface_worst_region_p95_mm"] <= plan.tolerance_mm
    assert metrics["surface_object_p95_mm"] <= plan.tolerance_mm
    assert metrics["surface_inner_disc_coverage"] > 0.95  # the disc inside the innermost ring is filled
    assert metrics["surface_completeness"] > 0.9
    # what the rings promise on the sphere the surface mostly covers (measured 93 %: short of the 95 %
    # the planner rehearsed, where the rings crowd on its flank), and what it misses is accounted for
    assert metrics["surface_object_coverage"] >= 0.9
    missed = metrics["surface_object_missed"]
    assert sum(missed.values()) == pytest.approx(1.0 - metrics["surface_object_coverage"], abs=2e-3)
    assert 0.5 < metrics["surface_object_promised"] < 1.0  # the strips beyond the limb's last ring are not


def test_a_plan_whose_object_fails_while_the_whole_view_passes_is_refused(
    pilot: tuple[list[PilotView], RingPlanSettings],
) -> None:
    """At 0.05 mm the densest rings the projector can show keep the view's p95 far within it (the
    bench is most of the area) but not the sphere's: the planner refuses, saying what would."""
    views, settings = pilot
    view = views[0]
    assert view.camera is not None and view.grid is not None
    center = ((view.projector.width - 1) / 2, (view.projector.height - 1) / 2)
    surface = pilot_surface(view.grid, view.camera, view.projector, center, settings.rehearsal_step_px)
    densest = np.arange(settings.min_radius_px, float(np.nanmax(surface.rho)), settings.min_spacing_px)
    found = rehearse([surface], densest, center, "quadratic", noise_mm(surface))
    assert found.quantile_mm <= 0.05 < found.worst_region_mm
    with pytest.raises(PlanError, match=r"every surface region within 0\.05 mm") as refused:
        plan_rings(views, settings, 0.05)
    assert "More rings" in str(refused.value)


def test_a_rehearsal_cuts_the_rings_out_of_the_pilot(pilot: tuple[list[PilotView], RingPlanSettings]) -> None:
    view = pilot[0][0]
    assert view.camera is not None and view.grid is not None
    center = (511.5, 383.5)
    surface = pilot_surface(view.grid, view.camera, view.projector, center)
    radii = np.linspace(30.0, 600.0, 12)
    points, _, ring = ring_samples(surface, radii)
    rho = ring_polar(view.projector, points, center)[0]
    assert len(points) > 1000 and np.percentile(np.abs(rho - radii[ring]), 99) < 0.5
    errors = [rehearse([surface], np.linspace(30.0, 600.0, n), center, "quadratic").rms_mm for n in (8, 32)]
    assert errors[1] < 0.5 * errors[0]


@pytest.mark.parametrize("tolerance", [0.0, -0.1, float("nan")])
def test_the_planner_refuses_a_tolerance_that_is_not_positive(
    pilot: tuple[list[PilotView], RingPlanSettings], tolerance: float
) -> None:
    with pytest.raises(PlanError, match="tolerance_mm"):
        plan_rings(pilot[0], pilot[1], tolerance)


def test_the_planner_refuses_an_empty_pilot_and_a_surface_the_rings_miss(
    pilot: tuple[list[PilotView], RingPlanSettings],
) -> None:
    views, settings = pilot
    empty = PilotView(np.zeros((0, 3)), views[0].projector, views[0].viewpoint)
    with pytest.raises(PlanError, match="no points"):
        plan_rings([empty], settings, 0.2)
    aside = PilotView(views[0].points + np.array([3000.0, 0.0, 0.0]), views[0].projector, views[0].viewpoint)
    assert not ring_polar(aside.projector, aside.points[:100], (511.5, 383.5))[2].any()
    with pytest.raises(PlanError, match="do not reach"):
        plan_rings([aside], settings, 0.2)


def test_a_plan_file_round_trips_and_a_bad_one_is_named(plans: dict[float, RingPlan], tmp_path: Path) -> None:
    plan = plans[0.2]
    path = tmp_path / "plan.json"
    plan.save(path)
    again = RingPlan.load(path)
    assert again.radii_px == pytest.approx(plan.radii_px, abs=0.01)
    assert again.tolerance_mm == 0.2 and again.criteria["rms_uniform"] == plan.criteria["rms_uniform"]
    data = json.loads(path.read_text())
    data["radii_px"] = [10.0, 12.0]
    path.write_text(json.dumps(data))
    with pytest.raises(PlanError, match="radii_px"):
        RingPlan.load(path)
    path.write_text("{}")
    with pytest.raises(PlanError, match="not a ring plan"):
        RingPlan.load(path)


def test_no_face_of_a_planned_surface_spans_a_depth_step() -> None:
    """A staircase, planned at 0.2 mm: every triangle of the surface between the rings has its
    three corners on one tread (the truth's regions, split where neighbouring true points jump
    more than 2 mm); a triangle joining two treads would put its pixels millimetres off both. Nor
    does the fill between the rings join two treads: hardly a filled pixel is a millimetre off."""
    from rig.config import config_from_dict
    from rig.evaluate.distances import surface_distances
    from rig.evaluate.wholeness import true_areas

    data = load_config().model_dump(mode="json")
    data["simulation"]["scene"] = {"kind": "steps"}
    config = config_from_dict(data, "steps")
    with open_rig(config) as rig:
        pilot = run_scan(rig, "phase")
        plan = plan_rings(pilot_views(pilot, rig.camera_models, rig.projector_models), config.scan.adaptive, 0.2)
        pair = run_scan(with_plan(rig, plan), "rings").pairs[0]
        assert rig.truth is not None and pair.surface is not None and pair.rings is not None
        truth = rig.truth.ground_truth(0, 0)
    _, region = true_areas(truth)
    height, width = region.shape
    xy = np.rint(pair.rings.camera_xy[pair.rings.kept]).astype(np.int64)
    corner = region[np.clip(xy[:, 1], 0, height - 1), np.clip(xy[:, 0], 0, width - 1)][pair.surface.faces]
    assert len(corner) > 10_000 and pair.surface.counts["dropped_depth_edge"] > 0
    assert ((corner == corner[:, :1]).all(axis=1)).all()
    filled = pair.surface.valid & (pair.surface.triangle < 0)
    assert filled.sum() > 1000
    # measured: 0.4 % over 1 mm (10 % before the fill checked its fit's misfit)
    assert (surface_distances(pair.surface.grid, filled, truth) > 1.0).mean() < 0.01
