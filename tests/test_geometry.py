"""Camera model and triangulation against analytic answers."""

from __future__ import annotations

import numpy as np
import pytest

from rig.geometry import CameraModel, look_at_rotation, ray_plane, ray_ray_midpoint
from rig.patterns import Correspondence
from rig.pipeline.dense import PairTriangulator
from tests.conftest import make_device


def test_look_at_is_a_right_handed_rotation_looking_at_the_target() -> None:
    pos = np.array([120.0, -40.0, 600.0])
    R = look_at_rotation(pos, np.zeros(3), np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[2], -pos / np.linalg.norm(pos))
    assert R[1] @ np.array([0.0, 1.0, 0.0]) < 0  # image down is world -y: world up appears up


@pytest.mark.parametrize("dist", [(), (-0.06, 0.04), (-0.2, 0.1, 0.002, -0.001, 0.01)])
def test_project_then_rays_returns_to_the_point(dist: tuple[float, ...]) -> None:
    cam = make_device(1280, 1024, 1800.0, (-100.0, 20.0, 600.0), dist=dist)
    rng = np.random.default_rng(3)
    points = rng.uniform([-150, -150, -20], [150, 150, 120], (500, 3))
    uv, _ = cam.project(points)
    origins, directions = cam.rays(uv)
    to_point = points - origins
    along = np.einsum("ij,ij->i", to_point, directions)
    off_ray = np.linalg.norm(to_point - along[:, None] * directions, axis=1)
    assert np.max(off_ray) < 1e-7


def test_orthographic_rays_are_parallel_and_project_back() -> None:
    proj = make_device(1024, 768, 2.0, (0.0, 0.0, 600.0), projection="orthographic")  # 2 px per mm
    uv = np.array([[0.0, 0.0], [511.5, 383.5], [1000.0, 700.0]])
    origins, directions = proj.rays(uv)
    np.testing.assert_allclose(directions, np.tile([0.0, 0.0, -1.0], (3, 1)), atol=1e-12)
    np.testing.assert_allclose(origins[1], [0.0, 0.0, 600.0], atol=1e-9)
    back, _ = proj.project(origins + 123.0 * directions)
    np.testing.assert_allclose(back, uv, atol=1e-9)


def test_ray_plane_matches_analytic_intersection() -> None:
    origins = np.array([[0.0, 0.0, 10.0], [1.0, 2.0, 3.0]])
    directions = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 0.0]])
    offsets = np.array([2.0, 7.0])  # z = 2; x + y = 7
    points, ok = ray_plane(origins, directions, normals, offsets)
    np.testing.assert_allclose(points, [[0.0, 0.0, 2.0], [5.0, 2.0, 3.0]])
    assert ok.all()
    _, ok = ray_plane(origins[:1], np.array([[1.0, 0.0, 0.0]]), normals[:1], offsets[:1])
    assert not ok[0]  # parallel ray


def test_ray_ray_midpoint_of_crossing_and_skew_rays() -> None:
    o1 = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    d1 = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    o2 = np.array([[5.0, -5.0, 0.0], [5.0, -5.0, 2.0]])
    d2 = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    points, gap, ok = ray_ray_midpoint(o1, d1, o2, d2)
    np.testing.assert_allclose(points, [[5.0, 0.0, 0.0], [5.0, 0.0, 1.0]])
    np.testing.assert_allclose(gap, [0.0, 2.0])
    assert ok.all()


def _analytic_correspondence(
    camera: CameraModel, projector: CameraModel, depth_plane_z: float, both: bool
) -> tuple[Correspondence, np.ndarray]:
    """Camera rays meet the plane z = depth_plane_z; the true projector coordinates of each point."""
    origins, directions = camera.pixel_rays
    s = (depth_plane_z - origins[:, 2]) / directions[:, 2]
    truth = origins + s[:, None] * directions
    uv, _ = projector.project(truth)
    shape = (camera.height, camera.width)
    inside = (
        (uv[:, 0] > 0) & (uv[:, 0] < projector.width - 1) & (uv[:, 1] > 0) & (uv[:, 1] < projector.height - 1)
    ).reshape(shape)
    corr = Correspondence(
        valid=inside,
        quality=np.ones(shape, np.float32),
        texture=np.zeros(shape, np.uint8),
        u=uv[:, 0].reshape(shape),
        v=uv[:, 1].reshape(shape) if both else None,
    )
    return corr, truth.reshape(*shape, 3)


@pytest.mark.parametrize("projector_dist", [(), (0.05, -0.02)])
@pytest.mark.parametrize("both", [False, True])
def test_pair_triangulation_returns_the_analytic_point(projector_dist: tuple[float, ...], both: bool) -> None:
    camera = make_device(320, 256, 450.0, (-100.0, 0.0, 600.0), dist=(-0.06, 0.04))
    projector = make_device(256, 192, 375.0, (100.0, 0.0, 620.0), dist=projector_dist)
    corr, truth = _analytic_correspondence(camera, projector, 17.0, both)
    points, valid = PairTriangulator(camera, projector).triangulate(corr)
    assert valid.sum() > 0.5 * valid.size
    np.testing.assert_array_equal(valid, corr.valid)
    assert np.max(np.abs(points[valid] - truth[valid])) < 1e-6


def test_pair_triangulation_with_orthographic_projector() -> None:
    camera = make_device(320, 256, 450.0, (-150.0, 0.0, 600.0))
    projector = make_device(256, 192, 0.8, (0.0, 0.0, 600.0), projection="orthographic")
    corr, truth = _analytic_correspondence(camera, projector, -5.0, both=False)
    points, valid = PairTriangulator(camera, projector).triangulate(corr)
    assert valid.any()
    assert np.max(np.abs(points[valid] - truth[valid])) < 1e-6


def test_reject_isolated_drops_mixed_pixels_and_keeps_steep_smooth_surfaces() -> None:
    from rig.pipeline.dense import reject_isolated

    camera = make_device(64, 48, 60.0, (0.0, 0.0, 600.0))
    origins, directions = camera.pixel_rays
    depth = np.full((48, 64), 500.0)
    depth[:, :31] = 600.0 + 1.5 * np.arange(31)  # steep but smooth: 1.5 mm per pixel
    depth[:, 31] = 560.0  # a column of mixed pixels on the edge between the two surfaces
    depth[40, 5] = 620.0  # an isolated error
    s = depth.ravel() / (directions @ camera.axis)
    grid = (origins + s[:, None] * directions).reshape(48, 64, 3)
    valid = np.ones((48, 64), dtype=bool)
    keep = reject_isolated(grid, valid, camera, max_jump_mm=2.0)
    assert not keep[:, 31].any()
    assert not keep[40, 5]
    assert keep[:, :31].sum() == 31 * 48 - 1  # every ramp point but the error
    assert keep[:, 32:].all()


def test_closest_on_first_ray_lies_on_the_first_ray() -> None:
    from rig.geometry.triangulate import closest_on_first_ray

    o1 = np.zeros((2, 3))
    d1 = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    o2 = np.array([[5.0, -5.0, 3.0], [5.0, -5.0, 3.0]])
    d2 = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # crossing above x = 5; parallel
    points, ok = closest_on_first_ray(o1, d1, o2, d2)
    np.testing.assert_allclose(points[0], [5.0, 0.0, 0.0])
    assert ok.tolist() == [True, False]
