"""A grid's mesh faces (rig.pipeline.mesh.grid_mesh), compiled by numba: each cell of four corners
with points is tested and turned into two triangles in one loop, with no (cells, 4) arrays of
corners and edge lengths (those were a scan's peak of memory)."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(nogil=True, cache=True)
def _meshed(index: np.ndarray, vertices: np.ndarray, footprint: np.ndarray, row: int, col: int, most: float) -> bool:
    """Whether the cell at (row, col) of the grid's vertex numbers `index` has four corners and no
    edge longer than `most` times its first corner's `footprint` (mm per pixel)."""
    corners = (index[row, col], index[row, col + 1], index[row + 1, col + 1], index[row + 1, col])
    if corners[0] < 0 or corners[1] < 0 or corners[2] < 0 or corners[3] < 0:
        return False
    longest = 0.0
    for k in range(4):  # each edge from corner k to the next, as rig.pipeline.mesh measured it
        here, there = corners[k], corners[(k + 1) % 4]
        squared = 0.0
        for c in range(3):
            squared += (vertices[there, c] - vertices[here, c]) ** 2
        longest = max(longest, np.sqrt(squared) / footprint[here])
    return longest <= most


@njit(**KERNEL)
def grid_faces(index: np.ndarray, vertices: np.ndarray, footprint: np.ndarray, most: float) -> np.ndarray:
    """(F, 3) int32 faces of the grid's cells (`index`: (rows, cols) vertex numbers, -1 none) whose
    four corners have points (`vertices` (V, 3), mm per pixel `footprint` (V,)) and no edge longer
    than `most` footprints: for the n kept cells in row-major order, first each one's triangle
    (a, c, b), then each one's (a, d, c), for corners a, b, c, d from its top left clockwise in the
    image (facing the camera)."""
    rows, cols = index.shape
    kept = 0
    for row in range(rows - 1):
        for col in range(cols - 1):
            kept += _meshed(index, vertices, footprint, row, col, most)
    faces = np.empty((2 * kept, 3), np.int32)
    n = 0
    for row in range(rows - 1):
        for col in range(cols - 1):
            if _meshed(index, vertices, footprint, row, col, most):
                a, b = index[row, col], index[row, col + 1]
                c, d = index[row + 1, col + 1], index[row + 1, col]
                faces[n, 0], faces[n, 1], faces[n, 2] = a, c, b
                faces[kept + n, 0], faces[kept + n, 1], faces[kept + n, 2] = a, d, c
                n += 1
    return faces
