"""Delaunay triangles of image points (rig.pipeline.triangulation, rig.kernels.delaunay): Qhull's
(but a few long thin ones along the convex hull), each circle empty, on points in general position,
ring-like samples a pixel apart along rings and ten across, and grids (points on edges, four on a
circle); coinciding points once, as the first of them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull, Delaunay, cKDTree

from rig.pipeline.triangulation import _qhull, delaunay, insertion_order

RNG = np.random.default_rng(5)


def _as_set(tri: np.ndarray) -> set[tuple[int, ...]]:
    return {tuple(sorted(t)) for t in tri.tolist()}


def _areas(xy: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = (xy[tri[:, k]] for k in range(3))
    return ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]) / 2


def _points_inside_circles(xy: np.ndarray, tri: np.ndarray) -> int:
    """How many points lie inside a triangle's circumcircle by more than rounding (none, for Delaunay)."""
    a, b, c = (xy[tri[:, k]] for k in range(3))
    d = 2 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    b2, c2 = ((b - a) ** 2).sum(axis=1), ((c - a) ** 2).sum(axis=1)
    u, v = b - a, c - a
    centre = a + np.column_stack([v[:, 1] * b2 - u[:, 1] * c2, u[:, 0] * c2 - v[:, 0] * b2]) / d[:, None]
    radius = np.linalg.norm(centre - a, axis=1)
    inside = cKDTree(xy).query_ball_point(centre, radius * (1 - 1e-9) - 1e-9)
    return sum(len(found) for found in inside)


def _ring_samples(rings: int = 30, spacing: float = 12.0) -> np.ndarray:
    """Samples a pixel apart along ellipses `spacing` apart, like a ring scan's in the image."""
    parts = []
    for k in range(1, rings + 1):
        a, b = spacing * k, 0.8 * spacing * k
        count = int(2 * np.pi * a)
        theta = np.sort(RNG.uniform(0, 2 * np.pi, count))
        ring = np.column_stack([640 + a * np.cos(theta), 512 + b * np.sin(theta)])
        parts.append(ring + RNG.normal(0, 0.05, (count, 2)))
    return np.vstack(parts)


def test_matches_qhull_on_points_in_general_position() -> None:
    xy = np.round(RNG.uniform([10, 20], [600, 400], size=(3000, 2)), 3)
    triangles = delaunay(xy)
    qhull = Delaunay(xy).simplices
    assert _as_set(triangles) <= _as_set(qhull)
    inside = (np.abs(xy - [305, 210]) < [245, 140]).all(axis=1)  # 50 px or more from the edges
    assert _as_set(qhull[inside[qhull].all(axis=1)]) <= _as_set(triangles)
    assert len(triangles) > 0.99 * len(qhull)
    assert (_areas(xy, triangles) > 0).all()  # counter-clockwise


def test_takes_coinciding_points_once_as_the_first_of_them() -> None:
    xy = RNG.uniform(0, 500, size=(2000, 2))
    triangles = delaunay(xy)
    doubled = np.vstack([xy[:50], xy])  # the first 50 coincide with the next 50
    again = delaunay(doubled)
    used = np.unique(again)
    assert not np.isin(np.arange(50, 100), used).any()
    assert _as_set(again) == _as_set(np.where(triangles < 50, triangles, triangles + 50))


@pytest.mark.parametrize("shape", ["rings", "grid"])
def test_each_circle_is_empty_and_the_hull_is_covered(shape: str) -> None:
    if shape == "rings":  # long thin triangles between rings: the insertion order's hard case
        xy = _ring_samples()
    else:  # points on edges and four on each circle: the degenerate cases
        xy = np.stack(np.meshgrid(np.arange(60.0), np.arange(45.0)), axis=-1).reshape(-1, 2)
    triangles = delaunay(xy)
    assert (_areas(xy, triangles) > 0).all()
    assert _points_inside_circles(xy, triangles) == 0
    covered = _areas(xy, triangles).sum() / ConvexHull(xy).volume
    assert 0.99 < covered <= 1 + 1e-9  # a tiling: no overlap, at most a sliver of the hull missing
    if shape == "grid":
        assert len(triangles) == 2 * 59 * 44  # every square in two
    edges = np.sort(np.vstack([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert uses.max() == 2  # an edge between two triangles at most


@pytest.mark.parametrize("shape", ["circle", "parabola"])
def test_points_on_one_circle_or_a_flat_curve_need_no_fallback(shape: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Points exactly on one circle (every four of them too: rounding would flip edges back and
    forth) and points along a nearly straight curve (long thin triangles, long walks) are the
    insertion's own to triangulate, not Qhull's."""
    import rig.pipeline.triangulation as triangulation

    def refuse(xy: np.ndarray) -> np.ndarray:
        raise AssertionError("fell back to Qhull")

    monkeypatch.setattr(triangulation, "_qhull", refuse)
    if shape == "circle":
        angle = np.sort(RNG.uniform(0, 2 * np.pi, 3000))
        xy = 1500.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    else:
        x = np.sort(RNG.uniform(0, 4000, 20000))
        xy = np.column_stack([x, 1e-4 * (x - 2000) ** 2])
    triangles = delaunay(xy)
    assert (_areas(xy, triangles) > 0).all()
    assert abs(_areas(xy, triangles).sum() / ConvexHull(xy).volume - 1) < 0.01
    if shape == "circle":
        assert len(triangles) >= len(xy) - 2 - 10  # a fan of the polygon, but a few along the hull


def test_where_the_insertion_gives_up_qhull_answers(monkeypatch: pytest.MonkeyPatch) -> None:
    import rig.pipeline.triangulation as triangulation

    xy = RNG.uniform(0, 300, size=(400, 2))
    expected = _as_set(delaunay(xy))

    class GivesUp:
        hilbert_distances = staticmethod(triangulation.delaunay_kernels.hilbert_distances)

        @staticmethod
        def insert_all(*arrays: np.ndarray) -> int:
            return -1

    monkeypatch.setattr(triangulation, "delaunay_kernels", GivesUp)
    assert expected <= _as_set(delaunay(xy))


def test_a_coordinate_that_is_not_finite_is_refused_and_minus_zero_is_zero() -> None:
    xy = RNG.uniform(0, 100, size=(50, 2))
    xy[7, 1] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        delaunay(xy)
    xy[7, 1] = 5.0
    xy[3], xy[20] = (0.0, 12.5), (-0.0, 12.5)  # equal points, other bits
    assert 20 not in delaunay(xy)  # the first of them is kept


def test_degenerate_inputs_give_no_triangles() -> None:
    assert delaunay(np.zeros((0, 2))).shape == (0, 3)
    assert delaunay(np.array([[0.0, 0.0], [1.0, 1.0]])).shape == (0, 3)
    line = np.column_stack([np.arange(20.0), 2 * np.arange(20.0) + 1])
    assert delaunay(line).shape == (0, 3)
    assert delaunay(np.ones((10, 2))).shape == (0, 3)


def test_qhull_fallback_gives_the_same_triangles() -> None:
    xy = RNG.uniform(0, 300, size=(500, 2))
    xy = np.vstack([xy, xy[:5]])
    ours, theirs = delaunay(xy), _qhull(xy)
    assert _as_set(ours) <= _as_set(theirs)
    assert len(ours) > 0.98 * len(theirs)
    assert (_areas(xy, theirs) > 0).all()
    assert theirs.max() < 500


def test_insertion_order_is_rounds_along_a_curve_the_same_each_time() -> None:
    xy = RNG.uniform(0, 1000, size=(20000, 2))
    order = insertion_order(xy)
    assert sorted(order.tolist()) == list(range(len(xy)))
    assert np.array_equal(order, insertion_order(xy.copy()))
    last_round = order[len(xy) // 2 + 1000 :]  # well inside the last round (about half the points)
    step = np.linalg.norm(np.diff(xy[last_round], axis=0), axis=1)
    shuffled = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert np.median(step) < 0.1 * np.median(shuffled)
    first = order[:200]  # an early round: spread over the whole box, not one corner of it
    assert np.ptp(xy[first], axis=0).min() > 800
