"""Patterns for setting up a bench (not for decoding): the projector lit or dark, a checkerboard to
judge overlap and keystone, a crosshair with centre and edge marks for aiming, and a focus target
(a Siemens star with 1- and 2-pixel checkers) to sharpen projector and camera lenses by."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

SETUP_PATTERNS = ("white", "black", "checkerboard", "crosshair", "focus")
Size = tuple[int, int]


def setup_pattern(name: str, size: Size, square_px: int = 32) -> np.ndarray:
    """The setup pattern `name` (SETUP_PATTERNS) at projector `size` (width, height), uint8;
    ValueError naming the known ones for any other name."""
    makers: dict[str, Callable[[Size, int], np.ndarray]] = {
        "white": lambda s, _: np.full((s[1], s[0]), 255, np.uint8),
        "black": lambda s, _: np.zeros((s[1], s[0]), np.uint8),
        "checkerboard": _checkerboard,
        "crosshair": _crosshair,
        "focus": _focus,
    }
    if name not in makers:
        raise ValueError(f"unknown setup pattern {name!r}; one of {', '.join(SETUP_PATTERNS)}")
    if name == "checkerboard" and not 1 <= square_px <= min(size):
        raise ValueError(f"square_px must be in [1, {min(size)}], got {square_px}")
    return makers[name](size, square_px)


def _checkerboard(size: Size, square: int) -> np.ndarray:
    width, height = size
    rows = (np.arange(height) // square)[:, None]
    cols = (np.arange(width) // square)[None, :]
    return np.where((rows + cols) % 2 == 0, 255, 0).astype(np.uint8)


def _crosshair(size: Size, square: int) -> np.ndarray:
    """A grid of thin lines every tenth of the image, a thick cross through the centre, marks
    at each edge's middle and a box around the centre square."""
    width, height = size
    image = np.zeros((height, width), np.uint8)
    for i in range(1, 10):
        image[:, round(i * width / 10)] = 160
        image[round(i * height / 10), :] = 160
    cx, cy = width // 2, height // 2
    thick = max(1, min(width, height) // 200)
    image[cy - thick : cy + thick + 1, :] = 255
    image[:, cx - thick : cx + thick + 1] = 255
    box = min(width, height) // 10
    image[cy - box : cy + box + 1, [cx - box, cx + box]] = 255
    image[[cy - box, cy + box], cx - box : cx + box + 1] = 255
    image[0 : 2 * thick + 1, :] = 255  # the image's border: where the projection ends
    image[-(2 * thick + 1) :, :] = 255
    image[:, 0 : 2 * thick + 1] = 255
    image[:, -(2 * thick + 1) :] = 255
    return image


def _focus(size: Size, square: int) -> np.ndarray:
    """A Siemens star (36 spokes) in the centre and 1- and 2-pixel checkers in the corners: sharp
    focus resolves the star close to its middle and keeps the checkers grey-free."""
    width, height = size
    y, x = np.mgrid[0:height, 0:width]
    cx, cy = (width - 1) / 2, (height - 1) / 2
    angle = np.arctan2(y - cy, x - cx)
    radius = np.hypot(x - cx, y - cy)
    spokes = (np.floor(angle / (2 * np.pi) * 72) % 2 == 0).astype(np.uint8) * 255
    image = np.where(radius < min(width, height) * 0.4, spokes, 0).astype(np.uint8)
    patch = min(width, height) // 6
    top, bottom, left, right = (
        slice(0, patch),
        slice(height - patch, height),
        slice(0, patch),
        slice(width - patch, width),
    )
    for fine, ys, xs in ((1, top, left), (2, top, right), (2, bottom, left), (1, bottom, right)):
        image[ys, xs] = np.where(((y[ys, xs] // fine) + (x[ys, xs] // fine)) % 2 == 0, 255, 0)
    return image


def sharpness(image: np.ndarray, full_scale: int = 255) -> float:
    """A focus figure: the variance of the image's Laplacian (higher is sharper), in counts²
    of an 8-bit image, so that it reads the same across bit depths."""
    laplacian = cv2.Laplacian(image.astype(np.float32), cv2.CV_32F)  # the 4-neighbour kernel
    _, deviation = cv2.meanStdDev(laplacian)
    return float(deviation[0, 0] ** 2) * (255.0 / full_scale) ** 2
