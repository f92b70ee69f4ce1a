"""The mesh of an organised grid (rig.pipeline.mesh.grid_mesh) against its rule in plain numpy:
a vertex at every stride-th pixel with a point, two triangles per cell whose four corners have
points and no edge longer than _MAX_STRETCH pixel footprints (a depth edge)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_device

from rig.pipeline.mesh import _MAX_STRETCH, grid_mesh


def _expected_faces(sub: np.ndarray, footprint: np.ndarray) -> np.ndarray:
    valid = np.isfinite(sub).all(axis=2)
    index = np.full(valid.shape, -1)
    index[valid] = np.arange(valid.sum())
    vertices = sub[valid]
    a, b, c, d = index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]
    cell = (a >= 0) & (b >= 0) & (c >= 0) & (d >= 0)
    quads = np.column_stack([a[cell], b[cell], c[cell], d[cell]])
    edges = [np.linalg.norm(vertices[quads[:, (k + 1) % 4]] - vertices[quads[:, k]], axis=1) for k in range(4)]
    longest = np.max([edge / footprint[quads[:, k]] for k, edge in enumerate(edges)], axis=0)
    quads = quads[longest <= _MAX_STRETCH]
    return np.vstack([quads[:, [0, 2, 1]], quads[:, [0, 3, 2]]])


@pytest.mark.parametrize("stride", [1, 2, 3])
def test_grid_mesh_keeps_the_cells_its_rule_keeps(stride: int) -> None:
    camera = make_device(64, 48, 80.0, (0.0, 0.0, 500.0))
    origins, directions = camera.pixel_rays
    depth = np.full(64 * 48, 500.0)
    depth[(np.arange(64 * 48) % 64) >= 40] = 300.0  # a step of 30 footprints: cells across it are not meshed
    grid = (origins + depth[:, None] * directions).reshape(48, 64, 3)
    rng = np.random.default_rng(3)
    grid[rng.random((48, 64)) < 0.05] = np.nan  # holes: cells beside them are not meshed
    colors = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    mesh = grid_mesh(grid, colors, camera, stride)
    sub = grid[::stride, ::stride]
    valid = np.isfinite(sub).all(axis=2)
    np.testing.assert_array_equal(mesh.vertices, sub[valid])
    np.testing.assert_array_equal(mesh.colors, colors[::stride, ::stride][valid])
    rows, cols = np.nonzero(valid)
    np.testing.assert_array_equal(mesh.pixel, rows * stride * 64 + cols * stride)
    expected = _expected_faces(sub, stride * camera.mm_per_px(sub[valid]))
    assert 0 < len(expected) < 2 * (valid.shape[0] - 1) * (valid.shape[1] - 1)  # some cells dropped
    assert mesh.faces.dtype == np.int32
    np.testing.assert_array_equal(mesh.faces, expected)
