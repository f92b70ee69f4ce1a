"""The stored scan's images: the preview's z-buffer."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rig.geometry import CameraModel
from rig.pipeline.pointset import PointSet
from rig.store import images


def _view() -> CameraModel:
    """A camera at the origin looking along +z, 64 x 48 pixels."""
    return CameraModel(64, 48, np.array([[50.0, 0, 31.5], [0, 50.0, 23.5], [0, 0, 1]]), np.eye(3), np.zeros(3))


def _cloud(points: np.ndarray, colours: np.ndarray) -> PointSet:
    n = len(points)
    normals = np.tile(np.array([0.0, 0.0, -1.0], np.float32), (n, 1))
    return PointSet(
        points, normals, colours.astype(np.uint8), np.ones(n, np.float32), np.zeros(n, np.uint8), np.arange(n)
    )


@pytest.mark.parametrize("block_points", [1 << 16, 1024])
def test_the_preview_shows_the_nearest_point_of_each_pixel_whatever_their_order(
    monkeypatch: pytest.MonkeyPatch, block_points: int
) -> None:
    # 1024 points per block: the near and the far points fall in different blocks
    monkeypatch.setattr(images, "BLOCK_POINTS", block_points)
    rng = np.random.default_rng(4)
    count = 3000
    xy = rng.uniform(-0.45, 0.45, (count, 2))  # all within the image
    depth = rng.uniform(100.0, 200.0, count)
    points = np.column_stack([xy * depth[:, None], depth])
    colours = rng.integers(0, 256, (count, 3))
    uv, _ = _view().project(points)
    pixel = np.rint(uv[:, 1]).astype(int) * 64 + np.rint(uv[:, 0]).astype(int)
    expected = {}
    for i in np.argsort(-depth):  # far first: the nearest point of a pixel stays
        expected[pixel[i]] = i
    for order in (np.arange(count), rng.permutation(count)):
        shown = cv2.imdecode(
            np.frombuffer(
                images.preview_png(_cloud(points[order], colours[order]), _view(), own_colors=True), np.uint8
            ),
            cv2.IMREAD_COLOR,
        )[..., ::-1].reshape(-1, 3)
        nearest = np.array(list(expected.values()))
        # lit straight on: intensity 0.18 + 0.82 * shade of the same colour for every point
        shade = float(
            np.clip(
                np.array([0.0, 0.0, -1.0]) @ (np.array([-0.4, -0.6, -0.7]) / np.linalg.norm([-0.4, -0.6, -0.7])), 0, 1
            )
        )
        want = ((0.18 + 0.82 * shade) * colours[nearest].astype(float)).astype(np.uint8)
        assert np.array_equal(shown[list(expected.keys())], want)
        untouched = np.setdiff1d(np.arange(64 * 48), list(expected.keys()))
        assert (shown[untouched] == 32).all()


def test_a_projector_sees_each_points_colour_at_its_pixel_the_nearest_winning() -> None:
    from rig.pipeline.pointset import PointSet
    from rig.store.images import projector_view
    from tests.conftest import make_device

    model = make_device(64, 48, 60.0, (0.0, 0.0, 0.0), (0.0, 0.0, 100.0))
    points = np.array([[0.0, 0.0, 500.0], [0.0, 0.0, 400.0], [60.0, 0.0, 500.0], [0.0, 0.0, -50.0]])
    colours = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 9, 9]], np.uint8)
    n = len(points)
    cloud = PointSet(points, np.zeros((n, 3)), colours, np.ones(n), np.zeros(n), np.arange(n))
    image = projector_view(cloud, model)
    (u0, v0), (u2, v2) = np.round(model.project(points[[0, 2]])[0]).astype(int)
    assert image.shape == (48, 64, 3)
    assert tuple(image[v0, u0]) == (0, 255, 0)  # the nearer of the two on the axis
    assert tuple(image[v2, u2]) == (0, 0, 255)
    assert (image.reshape(-1, 3) == 9).all(axis=1).sum() == 0  # behind the projector: not drawn
    assert (image.reshape(-1, 3).any(axis=1)).sum() == 2
