"""Delaunay triangles of image points (rig.pipeline.triangulation): OpenCV's, with corners found by
their coordinates, are the Delaunay triangles scipy's Qhull finds (but a few along the convex hull,
which Subdiv2D's outer virtual vertices take)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from rig.pipeline.triangulation import delaunay, hilbert_order

RNG = np.random.default_rng(5)


def _as_set(tri: np.ndarray) -> set[tuple[int, ...]]:
    return {tuple(sorted(t)) for t in tri.tolist()}


def test_delaunay_matches_qhull_and_takes_coinciding_points_once() -> None:
    xy = np.round(RNG.uniform([10, 20], [600, 400], size=(3000, 2)), 3)
    triangles = delaunay(xy)
    qhull = Delaunay(xy).simplices
    assert _as_set(triangles) <= _as_set(qhull)
    inside = (np.abs(xy - [305, 210]) < [245, 140]).all(axis=1)  # 50 px or more from the edges
    assert _as_set(qhull[inside[qhull].all(axis=1)]) <= _as_set(triangles)
    assert len(triangles) > 0.99 * len(qhull)
    doubled = np.vstack([xy, xy[:50]])  # the last 50 coincide with the first 50
    again = delaunay(doubled)
    assert again.max() < len(xy)  # each coinciding point triangulated once, as the first of them
    assert _as_set(again) == _as_set(triangles)


def test_hilbert_order_keeps_neighbours_close() -> None:
    xy = RNG.uniform(0, 1000, size=(5000, 2))
    order = hilbert_order(xy)
    assert sorted(order.tolist()) == list(range(len(xy)))
    step = np.linalg.norm(np.diff(xy[order], axis=0), axis=1)
    shuffled = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert np.median(step) < 0.1 * np.median(shuffled)
