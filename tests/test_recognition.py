"""Recognition: geodesic distances against exact ones, the synthetic face set, and the descriptor's
invariances."""

from __future__ import annotations

import numpy as np
import pytest

from rig.recognition.geodesic import geodesic_distances, height_field, sample

UP = np.array([0.0, 0.0, 1.0])


def _depth_map_points(height, spacing_mm: float = 0.3, half_mm: float = 70.0, noise_mm: float = 0.02):  # type: ignore[no-untyped-def]
    """Points of a surface z = height(x, y) as a camera above would sample it, with noise."""
    x, y = np.meshgrid(np.arange(-half_mm, half_mm, spacing_mm), np.arange(-half_mm, half_mm, spacing_mm))
    z = height(x, y)
    ok = np.isfinite(z)
    points = np.column_stack([x[ok], y[ok], z[ok]])
    return points + np.random.default_rng(0).normal(0.0, noise_mm, points.shape)


@pytest.mark.parametrize("shape", ["sphere", "plane"])
def test_geodesic_distances_are_within_2_percent_of_the_exact_ones(shape: str) -> None:
    radius = 80.0
    if shape == "sphere":
        points = _depth_map_points(
            lambda x, y: np.sqrt(np.where(x**2 + y**2 < (0.95 * radius) ** 2, radius**2 - x**2 - y**2, np.nan))
        )
        source = np.array([0.0, 0.0, radius])
    else:
        points = _depth_map_points(lambda x, y: 0.2 * x + 0.1 * y)  # a tilted plane
        source = np.zeros(3)
    field = height_field(points, source, UP, 72.0, 1.0)
    distance = geodesic_distances(field, source)
    query = points[np.random.default_rng(1).choice(len(points), 3000)]
    if shape == "sphere":
        exact = radius * np.arccos(np.clip(query @ source / (np.linalg.norm(query, axis=1) * radius), -1.0, 1.0))
    else:
        exact = np.linalg.norm(query - source, axis=1)
    found = sample(field, distance, query)
    measured = np.isfinite(found) & (exact > 10.0) & (exact < 65.0)
    assert measured.sum() > 1500
    relative = np.abs(found[measured] - exact[measured]) / exact[measured]
    assert relative.max() <= 0.02  # 1.4 % measured on both
    assert np.median(relative) < 0.006


def test_a_geodesic_does_not_step_across_a_depth_edge() -> None:
    """A block 20 mm high on a plane: the camera above sees no wall, and neither surface is reached
    from the other by stepping over the edge (a 3-cell step rises less than 80 degrees)."""
    points = _depth_map_points(lambda x, y: np.where((np.abs(x) < 15) & (np.abs(y) < 15), 20.0, 0.0))
    on_plane, on_block, beyond = np.array([[-40.0, 0.0, 0.0], [5.0, 0.0, 20.0], [40.0, 0.0, 0.0]])
    field = height_field(points, on_plane, UP, 85.0, 1.0)
    from_plane = sample(field, geodesic_distances(field, on_plane), np.array([on_block, beyond]))
    assert not np.isfinite(from_plane[0])  # unreached
    around = 2 * np.hypot(25.0, 15.0) + 30.0  # over the block's corners
    assert around * 0.99 <= from_plane[1] < around * 1.02
    from_block = sample(field, geodesic_distances(field, on_block), np.array([[-5.0, 0.0, 20.0], beyond]))
    assert abs(from_block[0] - 10.0) < 0.2 and not np.isfinite(from_block[1])
