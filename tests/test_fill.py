"""Which ring samples a filled pixel's fit may use (rig.pipeline.fill): one surface, however steeply
it turns from the camera, never two across a step."""

from __future__ import annotations

import numpy as np

from rig.geometry import CameraModel
from rig.pipeline.fill import FillSettings, _footprints, _one_surface

CAMERA = CameraModel(200, 200, np.array([[500.0, 0, 99.5], [0, 500.0, 99.5], [0, 0, 1]]), np.eye(3), np.zeros(3))


def _on_plane(columns: np.ndarray, normal: np.ndarray, through: np.ndarray) -> np.ndarray:
    """Where the rays of pixels (column, row 99.5) meet the plane through `through` with `normal`."""
    rays = np.column_stack([(columns - 99.5) / 500.0, np.zeros(len(columns)), np.ones(len(columns))])
    t = (through @ normal) / (rays @ normal)
    return rays * t[:, None]


def _use(points: np.ndarray, normals: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """The samples (all of ring 0 and 1 alternately) a pixel at column 99.5 may fit, nearest first."""
    xy = np.column_stack([columns, np.full(len(columns), 99.5)])
    ring = np.arange(len(columns)) % 2
    index = np.arange(len(columns))[None, :]
    dist = np.abs(columns - 99.5)[None, :]
    footprint = _footprints(points, normals, CAMERA, FillSettings())
    return _one_surface(points, footprint, xy, ring, (dist, index), np.array([1]), FillSettings())[0]


def test_a_flank_turned_80_degrees_from_the_camera_is_one_surface() -> None:
    columns = 100.0 + np.arange(8)
    slant = np.radians(80.0)
    normal = np.array([-np.sin(slant), 0.0, -np.cos(slant)])  # toward the camera, turned 80 degrees
    points = _on_plane(columns, normal, np.array([0.0, 0.0, 500.0]))
    apart = np.linalg.norm(np.diff(points, axis=0), axis=1) / CAMERA.mm_per_px(points[:-1])
    assert apart.min() > 3.0  # more than three footprints per image pixel: a step, to a camera-facing test
    assert _use(points, np.tile(normal, (len(columns), 1)), columns).all()


def test_samples_across_a_step_are_two_surfaces_and_the_pixel_is_left_open() -> None:
    columns = 100.0 + np.arange(8)
    facing = np.array([0.0, 0.0, -1.0])
    points = _on_plane(columns, facing, np.array([0.0, 0.0, 500.0]))
    points[4:] = _on_plane(columns[4:], facing, np.array([0.0, 0.0, 520.0]))  # 20 mm lower beyond a step
    assert not _use(points, np.tile(facing, (len(columns), 1)), columns).any()


def test_a_pixel_inside_the_innermost_ring_lists_each_sample_once() -> None:
    """Inside ring 0 a pixel's fit takes the nearest samples of any ring, then ring 0's not among
    them: a sample listed twice would weigh double in the fit."""
    from rig.pipeline.fill import _neighbourhoods

    xy = np.array([[10.0, 10.0], [12.0, 10.0], [30.0, 30.0], [60.0, 60.0]])
    dist, index = _neighbourhoods(
        xy, np.zeros(4, np.int64), np.array([[11.0, 11.0]]), np.array([0]), FillSettings(neighbours=4)
    )
    listed = index[0][np.isfinite(dist[0])]
    assert sorted(listed) == [0, 1, 2]  # the three in reach, once each (the fourth is beyond 48 px)


def test_each_pixels_neighbourhood_is_the_nearest_of_any_ring_then_of_each_of_its_rings() -> None:
    """_neighbourhoods against its definition, found by brute force: the k nearest samples of any
    ring within reach, then each ring's k / 2 nearest (k for ring 0 alone) not among those, and no
    neighbourhood where one of the pixel's rings has no sample in reach. Its search skips a ring
    whose nearest are all among the nearest of any ring: the lists must not change for it."""
    from rig.pipeline.fill import _neighbourhoods

    rng = np.random.default_rng(11)
    xy = rng.uniform([0, 0], [400, 300], (1500, 2))
    ring = np.minimum((np.hypot(xy[:, 0] - 200, xy[:, 1] - 150) // 30).astype(np.int64), 5)
    ring[(xy[:, 0] > 250) & (ring == 3)] = 4  # ring 3 only on the left: pixels on the right it does not reach
    ring[np.argsort(np.hypot(*(xy - 20.0).T))[:3]] = 6  # ring 6: three samples, fewer than its share
    at = rng.uniform([0, 0], [400, 300], (600, 2))
    annulus = np.minimum((np.hypot(at[:, 0] - 200, at[:, 1] - 150) // 30).astype(np.int64), 6)
    annulus[:100] = rng.integers(0, 7, 100)  # and some whose rings lie elsewhere
    at[100:110], annulus[100:110] = rng.uniform(16, 24, (10, 2)), 6  # beside ring 6's three samples
    settings = FillSettings(neighbours=8)
    k, reach = settings.neighbours, float(settings.reach_px)
    dist, index = _neighbourhoods(xy, ring, at, annulus, settings)
    members = np.bincount(ring, minlength=7)
    reached_some, skipped_some, skipped_short = 0, 0, 0
    for row in range(len(at)):
        d = np.hypot(*(xy - at[row]).T)
        order = np.argsort(d)
        nearest = [j for j in order[:k] if d[j] < reach]
        wanted = [0] if annulus[row] == 0 else [annulus[row] - 1, annulus[row]]
        share = k if annulus[row] == 0 else k // 2
        per_ring = [[j for j in order if ring[j] == r and d[j] < reach][:share] for r in wanted]
        listed = sorted(index[row][np.isfinite(dist[row])])
        if any(len(found) == 0 for found in per_ring):
            assert listed == [], row
            continue
        reached_some += 1
        # the search's own test: the nearest of any ring hold a ring's share, or all it has
        skipped = [sum(ring[j] == r for j in nearest) >= min(share, members[r]) for r in wanted]
        skipped_some += any(skipped)
        skipped_short += any(s and members[r] < share for s, r in zip(skipped, wanted, strict=True))
        expected = sorted(set(nearest) | {j for found in per_ring for j in found})
        assert listed == expected, row
        assert np.allclose(np.sort(dist[row][np.isfinite(dist[row])]), np.sort(d[expected]))
    assert reached_some > 200 and skipped_some > 50 and skipped_short > 0  # every kind of pixel was met


def test_the_reach_test_turns_away_only_pixels_with_a_ring_out_of_reach() -> None:
    """fill._rings_reach may let a pixel through that no sample reaches, never turn one away that
    both its rings reach (ring 0 alone inside it): the fill would find that pixel's neighbourhood."""
    from rig.pipeline.fill import _rings_reach

    rng = np.random.default_rng(5)
    xy = rng.uniform([0, 0], [640, 480], (3000, 2))
    ring = rng.integers(0, 6, len(xy))
    ring[(xy[:, 0] > 300) & (ring == 2)] = 3  # ring 2 only on the left half: far pixels of its annuli are out of reach
    pixel = rng.integers(0, 640 * 480, 5000)  # flat, in a 640 x 480 image
    annulus = rng.integers(-1, 7, len(pixel))
    reached = _rings_reach(xy, ring, pixel, (480, 640), annulus, 48.0)
    for x, y, a, through in zip(pixel % 640, pixel // 640, annulus, reached, strict=True):
        wanted = [0] if a == 0 else [a - 1, a]
        near = np.hypot(xy[:, 0] - x, xy[:, 1] - y) < 48.0
        both = a >= 0 and all((near & (ring == r)).any() for r in wanted)
        assert through or not both
        if a < 0 or a >= 6 or (x > 300 + 48 + 48 and 2 in wanted):  # rings 6 and 7 have no samples
            assert not through
    assert 0.1 < reached.mean() < 0.9
