"""Depth maps and preview renderings as PNG bytes."""

from __future__ import annotations

import cv2
import numpy as np

from rig.geometry import CameraModel
from rig.pipeline import PointSet
from rig.workers import BLOCK_POINTS, point_blocks

BLOCK_ROWS = 64  # rows of a grid projected at a time: no copy of the whole


def grid_depth(grid: np.ndarray, camera: CameraModel) -> np.ndarray:
    """(H, W) float32 camera-frame depth of organised points (H, W, 3), NaN where none."""
    depth = np.full(grid.shape[:2], np.nan, dtype=np.float32)
    for top in range(0, grid.shape[0], BLOCK_ROWS):
        rows = grid[top : top + BLOCK_ROWS]
        valid = np.isfinite(rows).all(axis=2)
        if valid.any():
            _, depth[top : top + BLOCK_ROWS][valid] = camera.project(rows[valid])
    return depth


def point_depth(points: np.ndarray, pixel: np.ndarray, shape: tuple[int, ...], camera: CameraModel) -> np.ndarray:
    """(H, W) float32 camera-frame depth of points (N, 3) at flat pixels `pixel` (N,), NaN elsewhere:
    what grid_depth gives for the organised grid of those points, a block of points at a time."""
    depth = np.full(int(np.prod(shape)), np.nan, dtype=np.float32)
    for part in point_blocks(len(points)):
        _, depth[pixel[part]] = camera.project(points[part])
    return depth.reshape(shape)


def depth_image_png(depth: np.ndarray, unit_mm: float = 1.0) -> bytes:
    """16-bit PNG of a depth image (mm, NaN = no point) in steps of `unit_mm` (rounded), 0 = no point."""
    valid = np.isfinite(depth)
    counts = np.zeros(depth.shape, dtype=np.uint16)
    counts[valid] = np.clip(np.rint(depth[valid] / unit_mm), 0, 65535).astype(np.uint16)
    return _png(counts)


def preview_png(cloud: PointSet, view: CameraModel, max_width: int = 960, own_colors: bool = False) -> bytes:
    """A shaded rendering of the cloud from `view` (usually the first camera): each point splatted
    into a z-buffer and lit by a light above-left of the viewer; background dark grey. Plaster
    white, or the points' own colours."""
    scale = min(1.0, max_width / view.width)
    width, height = int(view.width * scale), int(view.height * scale)
    image = np.full((height * width, 3), 32, dtype=np.uint8)
    nearest = np.full(height * width, np.inf)  # the z-buffer: a block of points at a time, no sort of the whole
    to_light = view.R.T @ np.array([-0.4, -0.6, -0.7])  # up-left of the viewer, toward it
    to_light /= np.linalg.norm(to_light)
    plaster = np.array([235, 225, 205], dtype=np.float64)
    for part in point_blocks(len(cloud), BLOCK_POINTS):  # the module's: a test makes it small
        uv, z = view.project(cloud.points[part])
        uv *= scale
        # clipped to one pixel off the image before the cast, so that a far point cannot wrap into it
        col = np.clip(np.rint(uv[:, 0]), -1, width).astype(np.int64)
        row = np.clip(np.rint(uv[:, 1]), -1, height).astype(np.int64)
        inside = np.flatnonzero((z > 0) & (col >= 0) & (col < width) & (row >= 0) & (row < height))
        pixel = row[inside] * width + col[inside]
        nearer = z[inside] <= nearest[pixel]
        inside, pixel = inside[nearer], pixel[nearer]
        # far first, so that of a pixel's points the nearest is written last (at equal depth the last in the cloud)
        order = np.argsort(-z[inside], kind="stable")
        inside, pixel = inside[order], pixel[order]
        nearest[pixel] = z[inside]
        shade = np.clip(cloud.normals[part][inside].astype(np.float64) @ to_light, 0.0, 1.0)
        tint = cloud.colors[part][inside].astype(np.float64) if own_colors else plaster
        image[pixel] = ((0.18 + 0.82 * shade)[:, None] * tint).astype(np.uint8)
    return _png(cv2.cvtColor(image.reshape(height, width, 3), cv2.COLOR_RGB2BGR))


def _png(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    if not ok:  # pragma: no cover - encoding a valid array does not fail
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def rgb_png(image: np.ndarray) -> bytes:
    """An RGB image (H, W, 3) uint8 as a PNG."""
    return _png(cv2.cvtColor(image, cv2.COLOR_RGB2BGR))


def mask_png(mask: np.ndarray) -> bytes:
    """A boolean mask as an 8-bit PNG: white where set."""
    return _png(np.where(mask, 255, 0).astype(np.uint8))


def depth_colour_jpeg(depth: np.ndarray) -> tuple[bytes, list[float] | None]:
    """Depth (mm, NaN or 0 where none) as a colour-mapped JPEG to look at (near red, far blue,
    none black) over its 1st to 99th percentile, and that range in mm (None without depth)."""
    found = np.isfinite(depth) & (depth > 0)
    image = np.zeros((*depth.shape, 3), np.uint8)
    span = None
    if found.any():
        low, high = (float(v) for v in np.percentile(depth[found], [1, 99]))
        scaled = np.clip((high - depth[found]) / max(high - low, 1e-6), 0, 1)
        colours = cv2.applyColorMap((scaled * 255).astype(np.uint8).reshape(-1, 1), cv2.COLORMAP_TURBO)
        image[found] = colours.reshape(-1, 3)
        span = [round(low, 2), round(high, 2)]
    ok, encoded = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise RuntimeError("JPEG encoding failed")
    return encoded.tobytes(), span


def projector_view(cloud: PointSet, model: CameraModel) -> np.ndarray:
    """What a projector "sees" of a cloud: each point's colour at the projector pixel it projects
    to, the nearest point winning (uint8 RGB, the projector's size; black where no point falls).
    Ring plans are drawn in projector pixels, so this is the picture to draw them over."""
    image = np.zeros((model.height, model.width, 3), np.uint8)
    uv, z = model.project(cloud.points)
    u, v = np.round(uv[:, 0]).astype(np.int64), np.round(uv[:, 1]).astype(np.int64)
    inside = (z > 0) & (u >= 0) & (u < model.width) & (v >= 0) & (v < model.height)
    order = np.argsort(-z[inside])  # far first: the nearest is written last
    image[v[inside][order], u[inside][order]] = cloud.colors[inside][order]
    return image
