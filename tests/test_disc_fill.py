"""The inner disc filled from the surface all around it (rig.pipeline.disc_fill), against a dome seen
by a pinhole camera whose every pixel's true point is known."""

from __future__ import annotations

import numpy as np
import pytest

import rig.pipeline.disc_fill
from rig.geometry import CameraModel
from rig.pipeline.disc_fill import disc_points

WIDTH, HEIGHT, DISC_PX = 160, 120, 18.0


def _dome() -> tuple[CameraModel, np.ndarray, np.ndarray]:
    """A camera at the origin looking along +z at a dome z = 300 - (x^2 + y^2) / 40 (mm): each
    pixel's true point (H*W, 3) and its distance in pixels from the image's centre."""
    k = np.array([[400.0, 0, 79.5], [0, 400.0, 59.5], [0, 0, 1]])
    camera = CameraModel(WIDTH, HEIGHT, k, np.eye(3), np.zeros(3))
    origins, directions = (np.asarray(a) for a in camera.pixel_rays)
    d = directions / directions[:, 2:3]  # the point is t * d with z = t
    a = (d[:, 0] ** 2 + d[:, 1] ** 2) / 40  # a t^2 + t - 300 = 0
    t = (-1 + np.sqrt(1 + 4 * a * 300)) / (2 * a)
    cols, rows = np.arange(WIDTH * HEIGHT) % WIDTH, np.arange(WIDTH * HEIGHT) // WIDTH
    return camera, origins + t[:, None] * d, np.hypot(cols - 79.5, rows - 59.5)


def _filled(camera: CameraModel, truth: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The disc's points found from the surface outside it, and their pixels."""
    covered = radius >= DISC_PX
    grid = np.where(covered[:, None], truth, np.nan)
    candidate = np.flatnonzero(~covered)
    return disc_points(grid, covered, candidate, np.zeros(len(candidate), dtype=np.int64), camera), candidate


def test_a_surface_quadratic_in_the_image_is_filled_exactly() -> None:
    """Distances along the rays quadratic in the pixel position: the thin plate's own kind."""
    camera, _, radius = _dome()
    origins, directions = (np.asarray(a) for a in camera.pixel_rays)
    cols, rows = np.arange(WIDTH * HEIGHT) % WIDTH, np.arange(WIDTH * HEIGHT) // WIDTH
    distance = 300 - 0.01 * (cols - 70.0) ** 2 + 0.004 * (cols - 70.0) * (rows - 50.0) - 0.02 * (rows - 50.0) ** 2
    truth = origins + distance[:, None] * directions
    found, candidate = _filled(camera, truth, radius)
    assert np.abs(found - truth[candidate]).max() < 1e-6


def test_a_dome_inside_the_disc_is_filled_close_to_the_truth() -> None:
    camera, truth, radius = _dome()
    found, candidate = _filled(camera, truth, radius)
    assert np.isfinite(found).all()
    error = np.linalg.norm(found - truth[candidate], axis=1)
    rise = np.ptp(truth[candidate, 2])  # the dome rises 4.4 mm inside the disc
    # measured 3.3 % at most: the dome's quartic term, which the rim's values and slopes do not show
    # (a plane through the rim, or a flat cap, would err by most of the rise)
    assert rise > 4 and error.max() < 0.05 * rise


def test_a_disc_left_open_or_read_as_another_annulus_is_not_filled() -> None:
    camera, truth, radius = _dome()
    cols = np.arange(WIDTH * HEIGHT) % WIDTH
    open_to_the_dark = (radius >= DISC_PX) & ~((cols > 79) & (np.abs(np.arange(WIDTH * HEIGHT) // WIDTH - 59.5) < 2))
    for covered, annulus in ((open_to_the_dark, 0), (radius >= DISC_PX, 3)):
        grid = np.where(covered[:, None], truth, np.nan)
        candidate = np.flatnonzero(radius < DISC_PX)  # the dark strip out to the edge is no candidate
        found = disc_points(grid, covered, candidate, np.full(len(candidate), annulus, dtype=np.int64), camera)
        assert np.isnan(found).all()


def test_a_disc_larger_than_the_solve_is_bounded_for_is_left_to_the_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    camera, truth, radius = _dome()
    found, _ = _filled(camera, truth, radius)
    assert np.isfinite(found).all()
    monkeypatch.setattr(rig.pipeline.disc_fill, "_MAX_DISC_PX", int((radius < DISC_PX).sum()) - 1)
    found, _ = _filled(camera, truth, radius)
    assert np.isnan(found).all()
