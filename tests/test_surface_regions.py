"""Errors of a surface by area and by region (rig.evaluate.regions): a steep object side counts by
the area it has, not by the pixels that see it, and a depth step splits the surface."""

from __future__ import annotations

import numpy as np

from rig.evaluate.regions import pixel_areas, region_errors, surface_regions, weighted_quantile


def _plane_grid(height: int, width: int, spacing_mm: float, slope: float = 0.0, z0: float = 0.0) -> np.ndarray:
    v, u = np.mgrid[0:height, 0:width].astype(float) * spacing_mm
    return np.stack([u, v, z0 + slope * u], axis=-1)


def test_a_pixel_stands_for_the_area_of_its_footprint() -> None:
    flat = _plane_grid(20, 30, 0.5)
    valid = np.ones((20, 30), bool)
    assert np.allclose(pixel_areas(flat, valid, 2.0), 0.25)
    steep = _plane_grid(20, 30, 0.5, slope=3.0)  # tilted: each pixel sees sqrt(1 + 9) times the area
    assert np.allclose(pixel_areas(steep, valid, 2.0), 0.25 * np.sqrt(10.0))
    valid[5, :] = False  # a row of holes: its neighbours keep their own footprints
    assert np.allclose(pixel_areas(flat, valid, 2.0), 0.25)


def test_a_depth_step_splits_the_surface_into_regions() -> None:
    grid = _plane_grid(10, 20, 0.5)
    grid[:, 10:, 2] += 8.0  # a step 8 mm high between columns 9 and 10
    valid = np.ones((10, 20), bool)
    labels = surface_regions(grid, valid, max_jump_mm=2.0)
    assert len(np.unique(labels)) == 2
    left, right = labels.reshape(10, 20)[:, :10], labels.reshape(10, 20)[:, 10:]
    assert len(np.unique(left)) == len(np.unique(right)) == 1 and left[0, 0] != right[0, 0]
    assert len(np.unique(surface_regions(grid, valid, max_jump_mm=10.0))) == 1


def test_the_weighted_quantile_counts_weight_not_samples() -> None:
    values = np.array([0.1, 0.2, 0.9])
    assert weighted_quantile(values, np.ones(3), 0.5) == 0.2
    assert weighted_quantile(values, np.array([1.0, 1.0, 8.0]), 0.5) == 0.9  # the heavy sample decides
    rng = np.random.default_rng(3)
    many = rng.random(1001)
    assert weighted_quantile(many, np.ones(1001), 0.95) == np.sort(many)[int(np.ceil(0.95 * 1001)) - 1]


def test_a_failing_object_is_not_hidden_by_a_large_flat_background() -> None:
    background = _plane_grid(40, 40, 0.5)
    valid = np.ones((40, 40), bool)
    object_rows = slice(15, 25), slice(15, 25)
    background[object_rows[0], object_rows[1], 2] += 20.0  # an object standing 20 mm proud
    distances = np.zeros(valid.sum())
    labels = surface_regions(background, valid, max_jump_mm=2.0)
    failing = np.zeros((40, 40), bool)
    failing[15:20, 15:25] = True  # half the object's surface is 0.5 mm off (3 % of the view); the rest exact
    distances[failing.ravel()] = 0.5
    areas = pixel_areas(background, valid, 2.0)
    whole, regions = region_errors(distances, areas, labels, q=0.95)
    assert np.isclose(areas.sum(), 40 * 40 * 0.25)  # the step's wall is no one's area
    assert whole.quantile_mm == 0.0  # 97 % of the view is exact: the whole view passes 0.2 mm
    assert [round(r.share, 4) for r in regions] == [round(1500 / 1600, 4), round(100 / 1600, 4)]
    assert regions[1].quantile_mm == 0.5  # the object, judged on its own, fails
    assert regions[0].quantile_mm == 0.0 and np.isclose(regions[1].rms_mm, np.sqrt(0.5 * 0.25))


def test_a_plan_on_a_rig_without_truth_is_recorded_unverified() -> None:
    from rig.service.adaptive import plan_check

    adaptive = {"tolerance_mm": 0.2, "pilot_scanned": False}
    assert plan_check(adaptive, {}) == {
        "promised_mm": 0.2,
        "quantile": 0.95,
        "rehearsed_on_this_object": False,
        "pilot_agreement_mm": None,
        "same_object_as_pilot": None,
        "held_out_ring_p95_mm": None,
        "measured_worst_region_p95_mm": None,
        "met": None,
        "verified": False,
        "tolerance": "unverified",
    }
    # its own rings bound it: the surface of every other ring within the tolerance of the others
    assert plan_check({**adaptive, "held_out_ring_p95_mm": 0.15}, {})["tolerance"] == "bounded"
    assert plan_check({**adaptive, "held_out_ring_p95_mm": 0.35}, {})["tolerance"] == "unverified"
    assert plan_check({**adaptive, "pilot_agreement_mm": 0.05}, {})["tolerance"] == "rehearsed"
    failing = {"projector0/camera0": {"surface_worst_region_p95_mm": 0.33}, "merged": {"rms_mm": 0.1}}
    assert plan_check({**adaptive, "pilot_scanned": True}, failing)["met"] is False
