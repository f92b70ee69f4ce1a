"""Solid textures for the simulated bench: a colour at every point in space, so any mesh or
built-in scene can be painted without texture coordinates, and the true colour of every camera
pixel is known (the colour at the surface point its centre sees).

Colours are linear RGB in [0, 1]. Every texture is a pure function of the world point.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np


@dataclass(frozen=True, eq=False)
class PlanarTexture:
    """A printed image on a planar object: albedo image (H, W) float32 in [0, 1], `mm_per_px` of
    it, and the plane's frame in the world: point = origin + x * axes[:, 0] + y * axes[:, 1], with
    image pixel (col, row) at (x, y) = ((col + 0.5) * mm_per_px, (row + 0.5) * mm_per_px)."""

    image: np.ndarray
    mm_per_px: float
    origin: np.ndarray
    axes: np.ndarray  # (3, 3) columns: the plane's x, y and normal in world coordinates


class SolidTexture(Protocol):
    """The albedo (linear RGB in [0, 1]) at world points (N, 3) -> (N, 3) float32."""

    def colour_at(self, points: np.ndarray) -> np.ndarray: ...


def _unit(direction: tuple[float, float, float]) -> np.ndarray:
    d = np.asarray(direction, dtype=np.float64)
    return d / np.linalg.norm(d)


def _pick(choice: np.ndarray, colours: tuple[tuple[float, float, float], ...]) -> np.ndarray:
    palette = np.asarray(colours, dtype=np.float32)
    return palette[choice % len(palette)]


@dataclass(frozen=True)
class Stripes:
    """Parallel slabs across `direction`, one of each of `colours` (equally wide) per `period_mm`,
    the first centred on the origin (so the bench plane lies mid-slab; see Checker)."""

    period_mm: float
    direction: tuple[float, float, float]
    colours: tuple[tuple[float, float, float], ...]

    def colour_at(self, points: np.ndarray) -> np.ndarray:
        width = self.period_mm / len(self.colours)
        band = np.floor(points @ _unit(self.direction) / width + 0.5).astype(np.int64)
        return _pick(band, self.colours)


@dataclass(frozen=True)
class Checker:
    """A three-dimensional checkerboard of cubes `size_mm` on a side (on a plane: squares), cubes
    centred on the origin: a plane through it (the bench plane z = 0) lies mid-cube, not on a face
    where rounding would choose the colour pixel by pixel."""

    size_mm: float
    colours: tuple[tuple[float, float, float], ...]

    def colour_at(self, points: np.ndarray) -> np.ndarray:
        cell = np.floor(points / self.size_mm + 0.5).astype(np.int64).sum(axis=1)
        return _pick(cell, self.colours)


@dataclass(frozen=True)
class Gradient:
    """Smooth colour: each channel 0.5 + 0.4 cos(2 pi (k_c . x) / period + phase_c), the three
    channels along different directions in the bench plane, so hue and brightness both vary."""

    period_mm: float

    def colour_at(self, points: np.ndarray) -> np.ndarray:
        angles = np.radians([0.0, 60.0, 120.0])
        directions = np.column_stack([np.cos(angles), np.sin(angles), np.full(3, 0.3)])
        phase = points @ directions.T * (2 * np.pi / self.period_mm) + np.array([0.0, 1.0, 2.0])
        return (0.5 + 0.4 * np.cos(phase)).astype(np.float32)


@dataclass(frozen=True, eq=False)
class Decal:
    """A printed image (H, W, 3 linear RGB, float32) laid on everything from above: the point
    (x, y, z) takes the image's colour at (x, y), the image `size_mm` wide and centred at
    `center_mm`; outside it, the image's edge colour."""

    image: np.ndarray
    size_mm: float
    center_mm: tuple[float, float]

    def colour_at(self, points: np.ndarray) -> np.ndarray:
        h, w = self.image.shape[:2]
        scale = w / self.size_mm
        col = (points[:, 0] - self.center_mm[0]) * scale + w / 2 - 0.5
        row = (self.center_mm[1] - points[:, 1]) * scale + h / 2 - 0.5  # image rows run toward -y
        col, row = np.clip(col, 0, w - 1), np.clip(row, 0, h - 1)  # outside: the edge colour
        c0, r0 = np.minimum(col.astype(np.int64), w - 2), np.minimum(row.astype(np.int64), h - 2)
        fc, fr = (col - c0)[:, None], (row - r0)[:, None]
        top = self.image[r0, c0] * (1 - fc) + self.image[r0, c0 + 1] * fc
        bottom = self.image[r0 + 1, c0] * (1 - fc) + self.image[r0 + 1, c0 + 1] * fc
        return (top * (1 - fr) + bottom * fr).astype(np.float32)


def read_decal_image(path: str, max_side: int = 4096) -> np.ndarray:
    """An 8- or 16-bit image file as linear RGB float32 in [0, 1] (sRGB decoded); ValueError if
    it cannot be read, is under 2 px or over `max_side` px on a side."""
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ValueError(f"cannot read an image from {path}")
    if min(image.shape[:2]) < 2 or max(image.shape[:2]) > max_side:
        raise ValueError(f"{path} is {image.shape[1]}x{image.shape[0]}: a decal is 2 to {max_side} px on a side")
    scale = 65535.0 if image.dtype == np.uint16 else 255.0
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    image = cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / np.float32(scale)
    return np.where(image <= 0.04045, image / 12.92, ((image + 0.055) / 1.055) ** 2.4).astype(np.float32)


def paint_planar_textures(
    albedo: np.ndarray,
    points: np.ndarray,
    faces: np.ndarray,
    textures: Sequence[PlanarTexture | None],
    face_object: np.ndarray,
) -> None:
    """Albedo of printed planes, averaged over 4x4 samples per pixel: the sub-pixel positions on
    the plane come from the local derivatives of the plane coordinates across the pixel grid.
    `textures`: each scene object's (None: not printed); `face_object`: each face's object."""
    shape = albedo.shape[:2]
    for index, tex in enumerate(textures):
        if tex is None:
            continue
        mine = ((faces >= 0) & (face_object[np.maximum(faces, 0)] == index)).reshape(shape)
        rows, cols = np.flatnonzero(mine.any(axis=1)), np.flatnonzero(mine.any(axis=0))
        if len(rows) == 0:
            continue
        # The plane's bounding box and a pixel around it: each pixel's samples need its own derivative
        # alone, and the derivative its neighbours; the rest of the view is not painted.
        box = (slice(max(rows[0] - 1, 0), rows[-1] + 2), slice(max(cols[0] - 1, 0), cols[-1] + 2))
        inside = mine[box]
        local = (points.reshape(*shape, 3)[box] - tex.origin) @ tex.axes[:, :2] / tex.mm_per_px - 0.5
        local[~inside] = np.nan  # texture pixel coordinates, on this plane only
        grid = local.astype(np.float32)
        d_row, d_col = np.gradient(grid, axis=(0, 1))
        for axis_grad in (d_row, d_col):  # at the edge of the plane, extend the derivative
            bad = ~np.isfinite(axis_grad)
            axis_grad[bad] = 0.0
        grid[~np.isfinite(grid)] = -1.0  # pixels of other objects: sampled, then not used
        total = np.zeros(inside.shape, dtype=np.float32)
        offsets = (np.arange(4, dtype=np.float32) + 0.5) / 4 - 0.5
        for dy in offsets:
            for dx in offsets:
                sample = grid + dx * d_col + dy * d_row
                total += cv2.remap(tex.image, sample, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        value = total / 16.0
        albedo[box][inside] = value[inside, None]
