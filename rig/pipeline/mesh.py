"""A triangle mesh of an organised grid of points (a depth map on the camera grid)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.geometry import CameraModel

# A grid cell whose edge is longer than this many times its pixel footprint is a depth edge seen
# within a pixel or two (a slope beyond 84 degrees to the camera): it is not meshed.
_MAX_STRETCH = 10.0


@dataclass(frozen=True, eq=False)
class Mesh:
    vertices: np.ndarray  # (V, 3) float64, mm
    colors: np.ndarray  # (V, 3) uint8 RGB
    faces: np.ndarray  # (F, 3) int32
    pixel: np.ndarray  # (V,) flat camera pixel of each vertex

    @staticmethod
    def concatenate(meshes: list[Mesh]) -> Mesh:
        """One mesh of several (at least one), faces renumbered (one mesh: itself, not a copy)."""
        if len(meshes) == 1:
            return meshes[0]
        offsets = np.cumsum([0, *(len(m.vertices) for m in meshes)])[:-1]
        faces = [
            m.faces.astype(np.int32, copy=False) + np.int32(offset) for m, offset in zip(meshes, offsets, strict=True)
        ]
        return Mesh(
            np.concatenate([m.vertices for m in meshes]),
            np.concatenate([m.colors for m in meshes]),
            np.concatenate(faces),
            np.concatenate([m.pixel for m in meshes]),
        )


def grid_mesh(grid: np.ndarray, colors: np.ndarray, camera: CameraModel, stride: int = 2) -> Mesh:
    """Vertices at every `stride`-th pixel of the grid (H, W, 3; NaN: no point) with their colours
    (H, W, 3 uint8), two triangles per cell whose four corners have points and no depth edge."""
    sub = grid[::stride, ::stride]
    rows, cols = sub.shape[:2]
    valid = np.isfinite(sub).all(axis=2)
    index = np.full((rows, cols), -1, dtype=np.int32)  # a grid's vertices are far fewer than 2**31
    index[valid] = np.arange(int(valid.sum()), dtype=np.int32)
    a, b = index[:-1, :-1], index[:-1, 1:]
    c, d = index[1:, 1:], index[1:, :-1]
    cell = (a >= 0) & (b >= 0) & (c >= 0) & (d >= 0)
    vertices = sub[valid]
    footprint = stride * camera.mm_per_px(vertices)
    quads = np.column_stack([a[cell], b[cell], c[cell], d[cell]])
    longest = np.zeros(len(quads))
    for k in range(4):  # a coordinate at a time: (quads, 3) temporaries were a mesh's peak of memory
        here, there = quads[:, k], quads[:, (k + 1) % 4]
        squared = sum((vertices[there, c] - vertices[here, c]) ** 2 for c in range(3))
        longest = np.maximum(longest, np.sqrt(squared) / footprint[here])
    quads = quads[longest <= _MAX_STRETCH]
    faces = np.vstack([quads[:, [0, 2, 1]], quads[:, [0, 3, 2]]])  # int32, facing the camera
    row, col = np.nonzero(valid)
    pixel = (row * stride) * camera.width + col * stride
    return Mesh(vertices, colors[::stride, ::stride][valid], faces, pixel)
