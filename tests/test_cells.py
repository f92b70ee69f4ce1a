"""The neighbour searches over a grid of cells (rig.kernels.cells) give what a k-d tree gives."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from rig.kernels.cells import k_nearest, pairs_within, sample_cells

RNG = np.random.default_rng(11)


@pytest.mark.parametrize("cell", [3.0, 20.0, 500.0])
def test_k_nearest_finds_the_k_d_trees_neighbours(cell: float) -> None:
    points = np.column_stack([RNG.uniform(0, 300, 2000), RNG.uniform(0, 200, 2000)])
    points[:300] = RNG.normal([150.0, 100.0], 3.0, size=(300, 2))  # a crowd, and sparse elsewhere
    queries = np.column_stack([RNG.uniform(-50, 350, 500), RNG.uniform(-50, 250, 500)])  # some outside
    index = np.empty((len(queries), 12), np.int64)
    k_nearest(points, sample_cells(points, cell), cell, queries, index, 0, len(queries))
    _, expected = cKDTree(points).query(queries, 12)
    np.testing.assert_array_equal(index, expected)


def test_pairs_within_are_the_k_d_trees_pairs() -> None:
    points = np.column_stack([RNG.uniform(0, 100, 3000), RNG.uniform(0, 80, 3000)])
    pairs = pairs_within(points, sample_cells(points, 4.0), 4.0, 4.0)
    assert (pairs[:, 0] < pairs[:, 1]).all()
    expected = cKDTree(points).query_pairs(4.0, output_type="ndarray")
    assert len(expected) > 1000
    assert {tuple(p) for p in pairs.tolist()} == {tuple(p) for p in expected.tolist()}
