"""Curvature of scanned surfaces against analytic shapes (rig.geometry.curvature)."""

from __future__ import annotations

import numpy as np
import pytest

from rig.geometry.curvature import curve_curvature, flat_noise, principal_curvatures

NOISE_MM = 0.03  # about the phase codec's noise on the default bench
VIEW = np.array([0.0, 0.0, 600.0])


def _grid(half: float, step: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.arange(-half, half, step), np.arange(-half, half, step))
    return x.ravel(), y.ravel()


def _noisy(points: np.ndarray, seed: int = 0) -> np.ndarray:
    return points + np.random.default_rng(seed).normal(0.0, NOISE_MM, points.shape)


def _interior(curvature, radius: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    return curvature.valid & (np.hypot(curvature.points[:, 0], curvature.points[:, 1]) < radius)


def test_a_sphere_reads_one_over_its_radius_in_both_directions() -> None:
    x, y = _grid(40.0)
    keep = x**2 + y**2 < 38.0**2
    z = np.sqrt(np.maximum(60.0**2 - x**2 - y**2, 0.0))
    c = principal_curvatures(_noisy(np.column_stack([x, y, z])[keep]), VIEW, radius_mm=5.0)
    inner = _interior(c, 25.0)
    assert inner.sum() > 100
    for k in (c.k1[inner], c.k2[inner]):
        assert abs(np.median(k) - 1 / 60) < 0.1 / 60  # convex toward the viewer reads positive
        assert np.percentile(np.abs(k - 1 / 60), 90) < 0.15 / 60


def test_a_hollow_reads_negative() -> None:
    x, y = _grid(30.0)
    keep = x**2 + y**2 < 28.0**2
    z = -np.sqrt(np.maximum(60.0**2 - x**2 - y**2, 0.0))  # the inside of a bowl, seen from above
    c = principal_curvatures(_noisy(np.column_stack([x, y, z])[keep]), VIEW, radius_mm=5.0)
    assert abs(np.median(c.mean[_interior(c, 20.0)]) + 1 / 60) < 0.1 / 60


def test_a_cylinder_bends_one_way_only_and_says_which() -> None:
    x, y = _grid(40.0)
    keep = np.abs(x) < 25.0
    z = np.sqrt(np.maximum(30.0**2 - x**2, 0.0))
    c = principal_curvatures(_noisy(np.column_stack([x, y, z])[keep]), VIEW, radius_mm=5.0)
    inner = c.valid & (np.abs(c.points[:, 0]) < 15.0) & (np.abs(c.points[:, 1]) < 30.0)
    assert abs(np.median(c.k1[inner]) - 1 / 30) < 0.1 / 30
    assert np.percentile(np.abs(c.k2[inner]), 90) < 0.1 / 30
    across = np.abs(c.dir1[inner, 0])  # the bending direction is across the axis (x)
    assert np.median(across) > 0.95
    across_axis = c.normal_curvature(np.tile([1.0, 0.0, 0.0], (len(c), 1)))
    assert np.allclose(across_axis[inner], c.k1[inner], atol=2e-3)


def test_a_plane_reads_zero_within_the_noise_the_fit_predicts() -> None:
    x, y = _grid(40.0)
    tilt = np.radians(20.0)
    points = np.column_stack([x, y * np.cos(tilt), y * np.sin(tilt)])
    c = principal_curvatures(_noisy(points), VIEW, radius_mm=5.0)
    inner = _interior(c, 30.0)
    spread = np.std(np.concatenate([c.k1[inner], c.k2[inner]]))
    predicted = np.median(flat_noise(c)[inner])
    assert spread < 0.002  # a radius of curvature beyond 500 mm
    assert 0.5 * predicted < spread < 2.0 * predicted


def test_a_larger_radius_smooths_noise_away() -> None:
    x, y = _grid(40.0)
    points = _noisy(np.column_stack([x, y, np.zeros_like(x)]))
    spreads = []
    for radius in (3.0, 6.0):
        c = principal_curvatures(points, VIEW, radius_mm=radius)
        spreads.append(np.std(c.k1[_interior(c, 25.0)]))
    assert spreads[1] < 0.5 * spreads[0]


def test_a_single_curve_is_not_a_surface() -> None:
    t = np.linspace(0, 2 * np.pi, 4000)
    circle = np.column_stack([40 * np.cos(t), 40 * np.sin(t), np.zeros_like(t)])
    assert principal_curvatures(circle, VIEW, radius_mm=5.0).valid.mean() < 0.05


def test_too_few_points_are_refused() -> None:
    with pytest.raises(ValueError, match="at least"):
        principal_curvatures(np.zeros((5, 3)), VIEW)


@pytest.mark.parametrize(("radius", "pitch"), [(20.0, 0.0), (15.0, 5.0)])
def test_curve_curvature_of_circles_and_helices(radius: float, pitch: float) -> None:
    t = np.linspace(0, 4 * np.pi, 3000, endpoint=False)
    c = pitch / (2 * np.pi)
    helix = np.column_stack([radius * np.cos(t), radius * np.sin(t), c * t])
    _, kappa = curve_curvature(_noisy(helix), step_mm=0.5, smooth_mm=3.0)
    truth = radius / (radius**2 + c**2)
    middle = kappa[len(kappa) // 5 : -len(kappa) // 5]
    assert abs(np.median(middle) - truth) < 0.05 * truth


def test_a_curve_too_short_is_refused() -> None:
    with pytest.raises(ValueError, match="too short"):
        curve_curvature(np.array([[0.0, 0, 0], [1.0, 0, 0]]), step_mm=0.5)
