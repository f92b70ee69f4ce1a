"""Errors of a surface by area and by region (rig.evaluate.regions): a steep object side counts by
the area it has, not by the pixels that see it, and a depth step splits the surface."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from rig.evaluate.promise import ProjectorRadius, _pieces, between_rings, polar_rows
from rig.evaluate.regions import (
    footprints,
    joined_labels,
    pixel_areas,
    region_errors,
    region_kernels,
    support_plane,
    surface_regions,
    weighted_quantile,
)
from rig.evaluate.wholeness import promised, true_areas


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
    assert len(np.unique(surface_regions(grid, valid, max_jump_mm=10.0, split_support=False))) == 1


def _cone_on_a_plane() -> tuple[np.ndarray, np.ndarray]:
    """A 60x60 view of a plane at 0.5 mm a pixel, and a cone rising from it with no step (slope
    0.6, 6 mm tall): the object joins its support wherever it touches it. Returns grid, cone."""
    grid = _plane_grid(60, 60, 0.5)
    r = np.hypot(grid[..., 0] - 15.0, grid[..., 1] - 15.0)
    grid[..., 2] = np.maximum(0.0, 0.6 * (10.0 - r))
    return grid, r < 7.0  # the cone, less its foot (within 3 pixel spacings of the plane)


def test_an_object_that_touches_its_support_without_a_step_is_a_region_of_its_own() -> None:
    grid, cone = _cone_on_a_plane()
    valid = np.ones(cone.shape, bool)
    assert len(np.unique(surface_regions(grid, valid, max_jump_mm=2.0, split_support=False))) == 1
    labels = surface_regions(grid, valid, max_jump_mm=2.0).reshape(cone.shape)
    assert len(np.unique(labels[cone])) == 1 and len(np.unique(labels[~cone])) == 2  # the plane, the cone's foot
    assert labels[cone][0] != labels[0, 0]
    tip = np.hypot(grid[..., 0] - 15.0, grid[..., 1] - 15.0) < 3.0
    distances = np.where(tip, 0.5, 0.0).ravel()  # the cone's tip 0.5 mm off: 4 % of the view, 18 % of the cone
    areas = pixel_areas(grid, valid, 2.0)
    joined = region_errors(distances, areas, surface_regions(grid, valid, 2.0, split_support=False), q=0.95)[1]
    assert max(r.quantile_mm for r in joined) == 0.0  # the plane hides it
    split = region_errors(distances, areas, labels.ravel(), q=0.95)[1]
    assert max(r.quantile_mm for r in split) == 0.5  # on its own it fails


def test_no_plane_large_enough_is_no_support() -> None:
    v, u = np.mgrid[0:50, 0:50].astype(float) * 0.5
    bowl = np.stack([u, v, 0.05 * ((u - 12) ** 2 + (v - 12) ** 2)], axis=-1)  # curved everywhere
    assert not support_plane(bowl, np.ones((50, 50), bool)).any()


def test_the_weighted_quantile_counts_weight_not_samples() -> None:
    values = np.array([0.1, 0.2, 0.9])
    assert weighted_quantile(values, np.ones(3), 0.5) == 0.2
    assert weighted_quantile(values, np.array([1.0, 1.0, 8.0]), 0.5) == 0.9  # the heavy sample decides
    rng = np.random.default_rng(3)
    many = rng.random(1001)
    assert weighted_quantile(many, np.ones(1001), 0.95) == np.sort(many)[int(np.ceil(0.95 * 1001)) - 1]


def test_each_regions_quantile_is_the_quantile_of_its_own_pixels() -> None:
    """region_errors takes each region's quantile from the whole surface's order, restricted to it:
    the same as the weighted quantile of the region's own distances and areas, ties included."""
    rng = np.random.default_rng(5)
    distances = np.round(rng.exponential(0.1, 20_000), 3).astype(np.float32)  # rounded: many ties
    areas = rng.uniform(0.1, 2.0, 20_000)
    labels = rng.choice(4, 20_000, p=[0.6, 0.3, 0.095, 0.005]).astype(np.int32)

    def quantile(values: np.ndarray, weights: np.ndarray) -> float:  # the rule, in numpy
        order = np.argsort(values, kind="stable")
        cumulative = np.cumsum(weights[order])
        return float(values[order][min(np.searchsorted(cumulative, 0.9 * cumulative[-1]), len(values) - 1)])

    whole, regions = region_errors(distances, areas, labels, q=0.9)
    assert whole.quantile_mm == weighted_quantile(distances, areas, 0.9) == quantile(distances, areas)
    assert len(regions) == 3  # the smallest label holds under MIN_REGION_SHARE of the area
    for label, region in zip((0, 1, 2), regions, strict=True):  # largest first
        own = labels == label
        assert region.quantile_mm == quantile(distances[own], areas[own])
        assert np.isclose(region.area_mm2, areas[own].sum())
        # its sums from one pass over every point, with no copy of its own
        assert np.isclose(
            region.rms_mm, np.sqrt(np.sum(areas[own] * distances[own].astype(float) ** 2) / areas[own].sum())
        )
        assert region.max_mm == distances[own].max() and np.isclose(region.share, areas[own].sum() / areas.sum())
    assert whole.max_mm == distances.max() and np.isclose(
        whole.rms_mm, np.sqrt(np.sum(areas * distances.astype(float) ** 2) / areas.sum())
    )


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


CENTRE = (60.0, 60.0)


def _rings_view(size: int = 120) -> tuple[np.ndarray, ...]:
    """A flat view with the rings' centre (CENTRE) in the middle of the image and projector
    coordinates = camera ones; rings every 10 px out to 50. Returns columns, radii, projector
    coordinates and the rings."""
    v, u = np.mgrid[0:size, 0:size].astype(float)
    c = size / 2
    return u, np.hypot(u - c, v - c), np.stack([u, v], axis=-1), np.arange(10.0, 51.0, 10.0)


def test_a_promise_past_2_to_the_15_sectors_is_the_same_in_int32() -> None:
    """An outer ring so large (50,000 px: some 39,000 sectors) that the annulus and sector images
    take int32: the promise is the one without it (nothing sees that ring)."""
    u, _, uv, radii = _rings_view()
    region, area, seen = np.zeros((120, 120), int), np.ones((120, 120)), u <= 85
    small = between_rings(polar_rows(uv, CENTRE), region, area, seen, radii)
    large = between_rings(polar_rows(uv, CENTRE), region, area, seen, np.append(radii, 50_000.0))
    assert small.any() and np.array_equal(large, small)


def test_label_totals_are_bincounts_to_the_bit() -> None:
    rng = np.random.default_rng(4)
    labels = rng.integers(-1, 40, 50_000).astype(np.int32)  # -1: no region, left out
    weights = rng.uniform(0.1, 3.0, 50_000).astype(np.float32)
    counted = labels >= 0
    expected = np.bincount(labels[counted], weights=weights[counted], minlength=40)
    assert np.array_equal(region_kernels.label_totals(labels, weights, 40), expected)


def test_a_surface_is_promised_between_two_rings_it_shows_not_beyond_the_last_one() -> None:
    u, rho, uv, radii = _rings_view()
    seen = u <= 85  # a shadow over the columns right of 85
    region, area = np.zeros((120, 120), int), np.ones((120, 120))
    target = between_rings(polar_rows(uv, CENTRE), region, area, seen, radii)
    assert target[(u < 55) & (rho < 48)].all()  # the disc and every band the camera sees both rings of
    assert not target[rho > 50].any()  # beyond the outermost ring
    assert target[60, 75] and target[36, 60]  # rings 10 and 20, and 20 and 30 (upwards), both seen
    # Right of the centre ring 30 lies in the shadow (column 90): the strip from ring 20 to the
    # shadow's edge has a ring on one side only, and is not promised; its mirror image is.
    assert not target[60, 84] and target[60, 36]
    # A second surface beside (another region, from column 86) does not lend its rings: the strip
    # of the first beyond ring 20 is one-sided again, while the second's band 30-40 is promised.
    region[:, 86:] = 1
    split = between_rings(polar_rows(uv, CENTRE), region, area, np.ones_like(seen), radii)
    assert not split[60, 84] and not split[60, 88] and split[60, 95]


def test_a_ring_seen_beyond_a_shadow_line_does_not_bound_the_strip_before_it() -> None:
    # One surface, a shadow line two pixels wide across the band between rings 30 and 40 on the
    # right, open at its ends: the band's surface joins around it, but along each projector ray the
    # strip before the line reaches ring 30 only.
    u, _, uv, radii = _rings_view()
    seen = np.ones((120, 120), bool)
    seen[50:71, 95:97] = False
    target = between_rings(polar_rows(uv, CENTRE), np.zeros((120, 120), int), np.ones((120, 120)), seen, radii)
    assert not target[60, 93] and not target[60, 98]  # between ring 30 (column 90) and the line; it and 40
    assert target[40, 93] and target[60, 27]  # above the line's end; the same band on the left
    # A ring the camera sees only at the brink of a shadow is not seen: a shadow from column 101 on
    # leaves ring 40 (column 100) one pixel clear, and the band 30-40 there is not promised.
    seen = u <= 100
    target = between_rings(polar_rows(uv, CENTRE), np.zeros((120, 120), int), np.ones((120, 120)), seen, radii)
    assert not target[60, 95] and target[60, 25]


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


def test_holes_are_found_where_the_rings_promise_a_surface_and_measured_by_its_depth() -> None:
    """A flat surface 1000 mm from a camera of f = 1000 px (1 mm a pixel) with a 10 x 12 px hole
    inside the rings and another beyond the outermost ring found: one hole of 120 mm^2."""
    from rig.geometry import CameraModel
    from rig.pipeline.holes import surface_holes
    from rig.pipeline.surface import RingBands, RingSurface

    width, height = 80, 60
    camera = CameraModel(
        width, height, np.array([[1000.0, 0, 39.5], [0, 1000.0, 29.5], [0, 0, 1]]), np.eye(3), np.zeros(3)
    )
    rows, cols = np.mgrid[0:height, 0:width]
    grid = np.dstack([(cols - 39.5), (rows - 29.5), np.full((height, width), 1000.0)]).astype(np.float64)
    valid = np.ones((height, width), bool)
    valid[20:30, 30:42] = False  # inside the rings: a hole
    valid[:, 70:] = False  # beyond the outermost ring the pair found: not promised
    annulus = np.where(cols < 70, 1, 5).astype(np.int16)
    grid[~valid] = np.nan
    vertices = np.zeros((3, 3))
    surface = RingSurface(vertices, np.tile([0, 0, -1.0], (3, 1)), np.array([[0, 1, 2]]), grid, valid, {},
                          np.array([0, 1, 1]), np.full((height, width), -1, np.int32))  # fmt: skip
    bands = RingBands(annulus, np.full((height, width), np.nan, np.float32), np.array([10.0, 20.0]), (40.0, 30.0))
    holes = surface_holes(surface, bands, np.ones((height, width), bool), camera)
    assert holes["holes"] == 1 and holes["largest"][0]["pixels"] == 120
    assert holes["area_mm2"] == pytest.approx(120.0, rel=1e-6)
    assert holes["largest"][0]["center_px"] == [35.5, 24.5]


def test_scattered_or_broken_points_find_no_support_and_never_fail() -> None:
    grid = _plane_grid(40, 40, 0.5)
    checker = (np.add.outer(np.arange(40), np.arange(40)) % 2).astype(bool)  # no two neighbours valid
    assert not support_plane(grid, checker).any()
    valid = np.ones((40, 40), bool)
    broken = grid.copy()
    broken[::3, ::3] = np.nan  # points lost at pixels still marked valid
    on = support_plane(broken, valid)
    assert on[1:, 1:][~np.isnan(broken[1:, 1:, 0])].all()  # the rest of the plane is still the support
    areas, labels = footprints(broken, valid, 2.0)
    assert len(areas) == len(labels) == valid.sum()


def test_surface_over_no_true_surface_is_judged_as_a_region_of_its_own() -> None:
    from rig.evaluate.surface import area_metrics

    valid = np.ones((20, 20), bool)
    true_area, true_region = np.full((20, 20), 0.25), np.zeros((20, 20), int)
    true_area[:, 16:], true_region[:, 16:] = 0.0, -1  # the truth sees nothing here: 20 % of the covered pixels
    dist = np.where(true_region < 0, 50.0, 0.01).ravel()  # a surface spanning empty space, 50 mm off
    metrics = area_metrics(valid, dist, (true_area, true_region))
    assert metrics["surface_worst_region_p95_mm"] == 50.0
    assert metrics["surface_area_p95_mm"] == 50.0  # a fifth of the area: the whole view's p95 sees it


def test_rhos_slope_at_the_missed_pixels_is_np_gradients() -> None:
    """wholeness measures the rings' crowding at the missed pixels alone: the same central
    differences, one-sided at the image's edges, as np.gradient over the whole image."""
    from rig.evaluate.wholeness import _gradient

    rng = np.random.default_rng(3)
    image = rng.normal(size=(130, 53)) * 100  # rows past a band (BAND_ROWS)
    y, x = np.nonzero(rng.random(image.shape) < 0.4)
    y, x = np.concatenate([y, [0, 129, 0, 129]]), np.concatenate([x, [0, 52, 52, 0]])  # the four corners
    made = ProjectorRadius(np.stack([image, np.zeros_like(image)], axis=-1), (0.0, 0.0))  # rho = |image|
    image = np.abs(image)
    rows, cols = np.gradient(image)
    assert np.array_equal(_gradient(made, y, x, 0), rows[y, x])
    assert np.array_equal(_gradient(made, y, x, 1), cols[y, x])
    assert np.array_equal(made.within(50.0), image < 50.0)


def test_a_truths_areas_are_made_once_and_shared_read_only() -> None:
    """Every scan of a standing scene is measured by the same true areas: made once for a truth,
    kept while it is, and read-only, so that no measurement can change the next one's."""
    hit = np.ones((20, 30), bool)
    truth = _Truth(_plane_grid(20, 30, 0.5), hit)
    area, region = true_areas(truth)  # type: ignore[arg-type]
    assert np.allclose(area, 0.25) and (region == 0).all()
    again = true_areas(truth)  # type: ignore[arg-type]
    assert again[0] is area and again[1] is region
    with pytest.raises(ValueError, match="read-only"):
        area[0, 0] = 1.0
    moved = _Truth(_plane_grid(20, 30, 1.0), hit)  # another scene: its own areas
    assert np.allclose(true_areas(moved)[0], 1.0)  # type: ignore[arg-type]


def test_a_truths_promise_is_kept_for_the_ring_sets_last_asked_for() -> None:
    """Each scan of a standing scene by the same rings is promised the same pixels: made once
    (between_rings, as made anew), shared read-only, kept for the last four ring sets asked for;
    a ring set asked for longest ago is made anew."""
    hit = np.ones((40, 50), bool)
    truth = _Truth(_plane_grid(40, 50, 0.5), hit)
    rows, cols = np.mgrid[0:40, 0:50].astype(np.float64)
    truth.projector_uv, truth.lit = np.stack([cols * 4.0, rows * 4.0], axis=-1), hit
    areas, centre = true_areas(truth), (100.0, 80.0)  # type: ignore[arg-type]
    sets = {name: np.array([20.0, 40.0, 60.0]) + shift for name, shift in zip("ABCDE", range(0, 10, 2), strict=True)}
    first = {name: promised(truth, sets[name], centre, areas) for name in "ABCD"}  # type: ignore[arg-type]
    made = between_rings(polar_rows(truth.projector_uv, centre), areas[1], areas[0], hit, sets["A"])
    assert np.array_equal(first["A"], made) and first["A"].any() and not first["A"].all()
    assert not np.array_equal(first["A"], first["D"])
    with pytest.raises(ValueError, match="read-only"):
        first["A"][0, 0] = False
    assert promised(truth, sets["A"], centre, areas) is first["A"]  # type: ignore[arg-type]  # asked for again
    promised(truth, sets["E"], centre, areas)  # type: ignore[arg-type]  # a fifth: B, asked for longest ago, goes
    assert promised(truth, sets["A"], centre, areas) is first["A"]  # type: ignore[arg-type]
    again = promised(truth, sets["B"], centre, areas)  # type: ignore[arg-type]
    assert again is not first["B"] and np.array_equal(again, first["B"])


class _Truth:
    """The parts of a bench's pixel truth the areas (and, given projector_uv and lit, the promise)
    are made from."""

    def __init__(self, points: np.ndarray, hit: np.ndarray) -> None:
        self.points, self.hit = points, hit
        self.projector_uv: np.ndarray | None = None
        self.lit: np.ndarray | None = None


@pytest.mark.parametrize(("height", "width"), [(1, 1), (1, 9), (7, 1), (40, 33)])
def test_joined_labels_are_the_connected_components_of_the_valid_pixels_numbered_by_first_pixel(
    height: int, width: int
) -> None:
    rng = np.random.default_rng(height * 100 + width)
    valid = rng.random((height, width)) < 0.7
    right, down = rng.random((height, width - 1)) < 0.6, rng.random((height - 1, width)) < 0.6
    labels = joined_labels(right, down, valid)
    node = np.full((height, width), -1)
    node[valid] = np.arange(int(valid.sum()))
    a = np.concatenate([node[:, :-1][right & valid[:, :-1] & valid[:, 1:]], node[:-1][down & valid[:-1] & valid[1:]]])
    b = np.concatenate([node[:, 1:][right & valid[:, :-1] & valid[:, 1:]], node[1:][down & valid[:-1] & valid[1:]]])
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(len(labels), len(labels)))
    count, expected = connected_components(graph, directed=False)
    assert labels.max(initial=-1) + 1 == count
    assert np.array_equal(labels, expected)  # both number regions by their first pixel


@pytest.mark.parametrize(("height", "width"), [(1, 7), (63, 1), (64, 5), (65, 7), (130, 9)])
def test_the_promises_pieces_joined_a_band_of_rows_at_a_time_are_the_connected_ones(height: int, width: int) -> None:
    """The pieces (pixels of one region, annulus and sector, joined through 4-neighbours) are the
    connected components of each such cell, across the bands of rows they are joined in; a pixel of
    no region is a piece of its own."""
    rng = np.random.default_rng(height * 100 + width)
    labels = rng.integers(-1, 2, (height, width)).astype(np.int32)
    band, sector = (rng.integers(0, 2, (height, width)).astype(np.int32) for _ in range(2))
    labels[:, 0], band[:, 0], sector[:, 0] = 1, 0, 0  # one piece down every row, across every band's edge
    pieces = _pieces(labels, band, sector, np.array([10.0, 20.0]))
    cell = (labels * 3 + band) * 2 + sector
    expected = np.full((height, width), -1)
    for value in np.unique(cell[labels >= 0]):
        found, _ = ndimage.label(cell == value)
        expected[found > 0] = found[found > 0] + expected.max() + 1
    seen = labels >= 0
    pairs = np.unique(np.stack([pieces[seen], expected[seen]]), axis=1)
    assert pairs.shape[1] == len(np.unique(pieces[seen])) == len(np.unique(expected[seen]))  # one to one
    assert len(np.unique(pieces)) == len(np.unique(pieces[seen])) + int((~seen).sum())
    assert len(np.unique(pieces[:, 0])) == 1
