"""A triangle mesh of an organised grid of points (a depth map on the camera grid)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.geometry import CameraModel
from rig.lazy import lazy_module

mesh_kernels = lazy_module("rig.kernels.mesh")  # numba compiles on first use

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
    (H, W, 3 uint8), two triangles per cell whose four corners have points and no depth edge (its
    faces in one compiled pass, rig.kernels.mesh.grid_faces)."""
    sub = grid[::stride, ::stride]
    valid = np.isfinite(sub).all(axis=2)
    index = np.full(valid.shape, -1, dtype=np.int32)  # a grid's vertices are far fewer than 2**31
    index[valid] = np.arange(int(valid.sum()), dtype=np.int32)
    vertices = sub[valid]
    footprint = stride * camera.mm_per_px(vertices)
    faces = mesh_kernels.grid_faces(index, vertices, footprint, _MAX_STRETCH)
    row, col = np.nonzero(valid)
    pixel = (row * stride) * camera.width + col * stride
    return Mesh(vertices, colors[::stride, ::stride][valid], faces, pixel)
