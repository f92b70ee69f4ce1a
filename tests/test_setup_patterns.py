"""Setup patterns (aiming, focusing) and the camera views the console shows of them."""

from __future__ import annotations

import asyncio

import cv2
import numpy as np
import pytest

from drivers.base import Frame
from rig.api.frame_views import HISTOGRAM_BINS, frame_view
from rig.patterns.setup import SETUP_PATTERNS, setup_pattern, sharpness
from rig.service.frames import FrameTap, TappedFrame

SIZE = (400, 300)


def test_each_setup_pattern_fits_the_projector_and_shows_what_it_is_for() -> None:
    for name in SETUP_PATTERNS:
        image = setup_pattern(name, SIZE)
        assert image.shape == (300, 400) and image.dtype == np.uint8
    assert setup_pattern("white", SIZE).min() == 255 and setup_pattern("black", SIZE).max() == 0
    board = setup_pattern("checkerboard", SIZE, square_px=25)
    assert board[0, 0] == 255 and board[0, 25] == 0 and board[25, 0] == 0 and board[25, 25] == 255
    cross = setup_pattern("crosshair", SIZE)
    assert cross[150, :].min() == 255 and cross[:, 200].min() == 255  # the centre lines, whole
    assert cross[0, :].min() == 255 and cross[:, -1].min() == 255  # the border: where the image ends
    focus = setup_pattern("focus", SIZE)
    assert focus[0, 0] != focus[0, 1] and focus[0, 0] != focus[1, 0]  # 1-pixel checkers in a corner
    with pytest.raises(ValueError, match="unknown setup pattern"):
        setup_pattern("rainbow", SIZE)
    with pytest.raises(ValueError, match="square_px"):
        setup_pattern("checkerboard", SIZE, square_px=0)


def test_sharpness_falls_as_the_focus_pattern_blurs_at_any_bit_depth() -> None:
    focus = setup_pattern("focus", SIZE).astype(np.float32)
    figures = [sharpness(cv2.GaussianBlur(focus, (0, 0), sigma).astype(np.uint8)) for sigma in (0.5, 1.0, 2.0, 4.0)]
    assert figures == sorted(figures, reverse=True) and figures[0] > 4 * figures[-1]
    ten_bit = (focus * 4).astype(np.uint16)
    assert sharpness(ten_bit, 1023) == pytest.approx(sharpness(focus.astype(np.uint8)), rel=0.02)


def _tapped(image: np.ndarray, bit_depth: int = 8) -> TappedFrame:
    return TappedFrame(7, Frame(image, 1.0, 3, 5000.0, 2.0, bit_depth), 0.0)


def test_a_camera_view_marks_clipped_pixels_and_counts_the_histogram() -> None:
    image = np.full((100, 200), 128, np.uint16)
    image[:, :50] = 4095  # saturated, 12-bit
    image[:, 150:] = 10  # too dark
    view = frame_view(_tapped(image, 12), None, overlay=True)
    assert float(view.headers["X-Saturated-Fraction"]) == pytest.approx(0.25)
    assert float(view.headers["X-Dark-Fraction"]) == pytest.approx(0.25)
    counts = [int(c) for c in view.headers["X-Histogram"].split(",")]
    assert len(counts) == HISTOGRAM_BINS and sum(counts) == 100 * 200 and counts[-1] == 50 * 100
    decoded = cv2.imdecode(np.frombuffer(view.jpeg, np.uint8), cv2.IMREAD_COLOR)
    b, g, r = (decoded[50, 20].astype(int)), decoded[50, 100].astype(int), decoded[50, 180].astype(int)
    assert b[2] > 200 and b[0] < 60  # saturated: red (BGR)
    assert r[0] > 200 and r[2] < 60  # too dark: blue
    assert abs(int(g[0]) - 8) < 6 and abs(int(g[0]) - int(g[2])) < 6  # the rest grey, scaled from 12 bits
    small = frame_view(_tapped(image, 12), 50, overlay=False)
    assert cv2.imdecode(np.frombuffer(small.jpeg, np.uint8), cv2.IMREAD_GRAYSCALE).shape == (25, 50)
    assert view.headers["X-Exposure-Us"] == "5000" and view.headers["X-Gain"] == "2"


def test_the_tap_keeps_only_the_newest_frame_and_a_reader_waits_a_bounded_time() -> None:
    tap = FrameTap()
    assert asyncio.run(tap.next_after(0, 0, 0.05)) is None
    for k in range(5):
        tap.publish(0, Frame(np.zeros((2, 2), np.uint8), float(k), k, 1.0, 1.0))
    newest = asyncio.run(tap.next_after(0, 0, 1.0))
    assert newest is not None and newest.count == 5 and newest.frame.sequence == 4  # no queue: the newest
    assert asyncio.run(tap.next_after(0, 5, 0.05)) is None and tap.newest(1) is None
