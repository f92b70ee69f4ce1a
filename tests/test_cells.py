"""The neighbour searches over a grid of cells (rig.kernels.cells) give what a k-d tree gives; its
sorts by counting give numpy's stable orders."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from rig.kernels.cells import (
    every_nth_by_group,
    group_cell_side,
    group_cells,
    group_order,
    k_nearest,
    k_nearest_in_group,
    nearest_within,
    pairs_within,
    radix_order,
    sample_cells,
)

RNG = np.random.default_rng(11)


@pytest.mark.parametrize("cell", [3.0, 20.0, 500.0])
def test_k_nearest_finds_the_k_d_trees_neighbours(cell: float) -> None:
    points = np.column_stack([RNG.uniform(0, 300, 2000), RNG.uniform(0, 200, 2000)])
    points[:300] = RNG.normal([150.0, 100.0], 3.0, size=(300, 2))  # a crowd, and sparse elsewhere
    queries = np.column_stack([RNG.uniform(-50, 350, 500), RNG.uniform(-50, 250, 500)])  # some outside
    index = np.empty((len(queries), 12), np.int64)
    k_nearest(sample_cells(points, cell), cell, queries, index, 0, len(queries))
    _, expected = cKDTree(points).query(queries, 12)
    np.testing.assert_array_equal(index, expected)


def test_pairs_within_are_the_k_d_trees_pairs() -> None:
    points = np.column_stack([RNG.uniform(0, 100, 3000), RNG.uniform(0, 80, 3000)])
    pairs = pairs_within(points, sample_cells(points, 4.0), 4.0, 4.0)
    assert (pairs[:, 0] < pairs[:, 1]).all()
    expected = cKDTree(points).query_pairs(4.0, output_type="ndarray")
    assert len(expected) > 1000
    assert {tuple(p) for p in pairs.tolist()} == {tuple(p) for p in expected.tolist()}


def test_nearest_within_searches_one_group_within_the_reach() -> None:
    points = np.column_stack([RNG.uniform(0, 300, 3000), RNG.uniform(0, 200, 3000)])
    group = RNG.integers(0, 5, len(points))
    cells = group_cells(points, group, 5, 16.0)
    for query in RNG.uniform([0, 0], [300, 200], size=(200, 2)):
        for g in (0, 3):
            row_d, row_i = np.empty(6), np.empty(6, np.int64)
            found = nearest_within(cells, (16.0, g, 25.0), (query[0], query[1]), row_d, row_i)
            distance = np.linalg.norm(points - query, axis=1)
            mine = np.flatnonzero((group == g) & (distance < 25.0))
            expected = mine[np.argsort(distance[mine], kind="stable")][:6]
            assert found == len(expected)
            np.testing.assert_array_equal(row_i[:found], expected)
            np.testing.assert_allclose(row_d[:found], distance[expected])


def test_k_nearest_in_group_searches_each_querys_own_group_even_outside_the_grid() -> None:
    """Queries beyond the points' bounding box, a reach shorter than a cell, and a group with no
    points: each row holds its own group's nearest within the reach, then inf and -1."""
    points = np.column_stack([RNG.uniform(0, 300, 3000), RNG.uniform(0, 200, 3000)])
    group = RNG.integers(0, 4, len(points))  # group 4 has no points
    side = group_cell_side(points, 5, 16.0)
    cells = group_cells(points, group, 5, side)
    queries = np.column_stack([RNG.uniform(-20, 320, 300), RNG.uniform(-20, 220, 300)])
    query_group = RNG.integers(0, 5, len(queries))
    dist, index = np.empty((300, 5)), np.empty((300, 5), np.int64)
    k_nearest_in_group(cells, (side, 9.0), queries, query_group, dist, index, 0, len(queries))
    for q, (query, g) in enumerate(zip(queries, query_group, strict=True)):
        distance = np.linalg.norm(points - query, axis=1)
        mine = np.flatnonzero((group == g) & (distance < 9.0))
        expected = mine[np.argsort(distance[mine], kind="stable")][:5]
        np.testing.assert_array_equal(index[q, : len(expected)], expected)
        assert (index[q, len(expected) :] == -1).all() and np.isinf(dist[q, len(expected) :]).all()
    assert (index[query_group == 4] == -1).all()


def test_many_groups_widen_the_cells_so_the_grid_stays_bounded() -> None:
    points = np.column_stack([RNG.uniform(0, 2448, 100), RNG.uniform(0, 2048, 100)])
    assert group_cell_side(points, 8, 12.0) == 12.0  # 8 x 35,000 cells of 12 px: within the bound
    wide = group_cell_side(points, 1024, 12.0)
    cells = np.prod((np.ptp(points, axis=0) / wide).astype(int) + 1)  # as group_cells sizes its grid
    assert wide > 12.0 and 1024 * cells <= 1.05e6


def test_group_order_is_numpys_stable_order() -> None:
    group = RNG.integers(0, 40, 5000)
    group[:100] = 7  # a long run of one group: its members keep their order
    order, starts = group_order(group, 45)  # groups beyond the largest value are empty runs
    np.testing.assert_array_equal(order, np.argsort(group, kind="stable"))
    np.testing.assert_array_equal(starts, np.concatenate([[0], np.cumsum(np.bincount(group, minlength=45))]))


@pytest.mark.parametrize("step", [1, 4, 7])
def test_every_nth_by_group_takes_lexsorts_places(step: int) -> None:
    group = RNG.integers(0, 30, 4000)
    key = np.round(RNG.uniform(-np.pi, np.pi, 4000), 1)  # rounded: many ties, broken by index
    key[:50] = -0.0  # equal to 0.0 in order, as numpy takes it
    key[50:100] = 0.0
    expected = np.sort(np.lexsort((key, group))[::step])
    np.testing.assert_array_equal(every_nth_by_group(group, key, 30, step), expected)


@pytest.mark.parametrize("key_bits", [1, 12, 23, 40])
def test_radix_order_is_numpys_stable_order(key_bits: int) -> None:
    keys = RNG.integers(0, 2**key_bits, 6000)
    keys[:200] = keys[200]  # ties keep their order
    np.testing.assert_array_equal(radix_order(keys, key_bits), np.argsort(keys, kind="stable"))
