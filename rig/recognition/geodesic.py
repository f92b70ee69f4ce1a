"""Geodesic distances on a scanned surface from one point, on the surface as a height field.

A scan sees its surface from one direction, so the surface is (almost everywhere) a height field
over the plane across that direction. It is resampled on a square grid in that plane (`cell_mm`):
each cell's height is a plane fitted to its points (those within `LAYER_MM` of its highest: a lower
layer is a surface behind a depth edge), evaluated at the cell's centre. Dijkstra runs on the grid
with a stencil of 32 directions: every step (du, dv) with |du|, |dv| <= 3 and no common divisor,
weighted by its 3D length. A path between two stencil directions is longer than the straight line
by at most 1 / cos(9.2 deg) - 1 = 1.3 % (the widest gap between the directions, 18.4 deg, halved),
against 8 % for the 8 neighbours of an edge graph; tests/test_recognition.py measures it against
exact distances on a sphere and a tilted plane. A step is not taken across a depth edge: where it
rises more steeply than `MAX_SLOPE_DEG`, or where a cell it passes over is empty or off its line by
more than `STRAIGHT_MM`.

Holes narrower than `2 * FILL_MM` (between a sparse scan's rings, where an interpolated surface
left out a triangle) are filled linearly from the cells around them (`fill_holes`), so that ring
samples alone, or a surface with gaps, still give a connected field.

Chosen over the libraries of reference 5.6: the heat method (potpourri3d) and exact polyhedral
geodesics (gdist, pygeodesic) need a clean triangle mesh and a compiled dependency; a scan is a
cloud with holes, and this needs only SciPy.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import gcd

import numpy as np
from scipy.interpolate import LinearNDInterpolator
from scipy.ndimage import binary_dilation, distance_transform_edt, map_coordinates
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import QhullError

LAYER_MM = 1.0  # a cell's points this far below its highest are a surface behind a depth edge
MAX_SLOPE_DEG = 80.0  # a step rising more steeply than this crosses a depth edge ...
STRAIGHT_MM = 1.0  # ... as does one over a cell this far off the line between its ends
FILL_MM = 12.0  # an empty cell this close to a measured one is filled from the cells around its hole
STENCIL = [(du, dv) for du in range(-3, 4) for dv in range(0, 4) if (dv > 0 or du > 0) and gcd(du, dv) == 1]


@dataclass(frozen=True, eq=False)
class HeightField:
    """A surface resampled on a square grid across a viewing direction."""

    height: np.ndarray  # (rows, cols) along the axis at each cell's centre, NaN where no point falls
    origin: np.ndarray  # (3,) the centre of cell (0, 0) at height 0
    axes: np.ndarray  # (3, 3): rows are u (along columns), v (along rows), the axis (toward the viewer)
    cell_mm: float

    def points(self) -> np.ndarray:
        """(rows, cols, 3) the cells' points in space (NaN where empty)."""
        rows, cols = self.height.shape
        v, u = np.mgrid[0:rows, 0:cols] * self.cell_mm
        across = u[..., None] * self.axes[0] + v[..., None] * self.axes[1]
        return self.origin + across + self.height[..., None] * self.axes[2]

    def cell_of(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) fractional (row, column) of points projected along the axis."""
        local = (points - self.origin) @ self.axes[:2].T / self.cell_mm
        return local[:, ::-1]


def height_field(
    points: np.ndarray, centre: np.ndarray, axis: np.ndarray, radius_mm: float, cell_mm: float
) -> HeightField:
    """The points within `radius_mm` of the line through `centre` along `axis` (toward the viewer),
    as a height field across the axis (see the module docstring)."""
    axis = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, axis)
    u /= np.linalg.norm(u)
    axes = np.array([u, np.cross(axis, u), axis])
    local = (points - centre) @ axes.T
    local = local[np.hypot(local[:, 0], local[:, 1]) <= radius_mm]
    size = int(np.ceil(2 * radius_mm / cell_mm)) + 1
    cell = np.floor((local[:, :2] + radius_mm) / cell_mm + 0.5).astype(np.int64)
    flat = cell[:, 1] * size + cell[:, 0]
    top = np.full(size * size, -np.inf)
    np.maximum.at(top, flat, local[:, 2])
    layer = local[:, 2] >= top[flat] - LAYER_MM
    offset = (local[layer, :2] + radius_mm) / cell_mm - cell[layer]  # from the cell's centre, in cells
    height = _plane_at_centre(flat[layer], offset, local[layer, 2], size * size)
    origin = centre - radius_mm * (axes[0] + axes[1])
    return HeightField(height.reshape(size, size), origin, axes, cell_mm)


def fill_holes(field: HeightField, fill_mm: float = FILL_MM) -> HeightField:
    """The field with each empty cell within `fill_mm` of a measured one filled by linear
    interpolation over the measured cells around its hole (Delaunay); cells outside their hull and
    farther away stay empty."""
    known = np.isfinite(field.height)
    reach = fill_mm / field.cell_mm
    gap = ~known & (distance_transform_edt(~known) <= reach)
    if not gap.any() or known.sum() < 3:
        return field
    rim = known & binary_dilation(gap, np.ones((3, 3), bool))  # a hole's edge is enough to span it
    rows, cols = np.nonzero(rim)
    try:
        fill = LinearNDInterpolator(np.column_stack([rows, cols]), field.height[rim])
    except QhullError:  # the rim is degenerate (its cells on one line)
        return field
    height = field.height.copy()
    height[gap] = fill(np.column_stack(np.nonzero(gap)))
    return HeightField(height, field.origin, field.axes, field.cell_mm)


def _plane_at_centre(cell: np.ndarray, offset: np.ndarray, height: np.ndarray, cells: int) -> np.ndarray:
    """Per cell, the least-squares plane h = a + b du + c dv through its points, at du = dv = 0 (the
    mean where the points cannot fix a plane); NaN where a cell has none."""

    def total(values: np.ndarray | float) -> np.ndarray:
        return np.bincount(cell, np.broadcast_to(values, cell.shape), minlength=cells)

    du, dv = offset[:, 0], offset[:, 1]
    n, su, sv, sh = total(1.0), total(du), total(dv), total(height)
    suu, suv, svv, suh, svh = total(du * du), total(du * dv), total(dv * dv), total(du * height), total(dv * height)
    normal = np.stack(
        [np.stack([n, su, sv], -1), np.stack([su, suu, suv], -1), np.stack([sv, suv, svv], -1)], -2
    )  # (cells, 3, 3)
    solvable = (n >= 4) & (np.abs(np.linalg.det(normal)) > 1e-6 * np.maximum(n, 1) ** 3)
    mean = np.where(n > 0, sh / np.maximum(n, 1), np.nan)
    if solvable.any():
        rhs = np.stack([sh, suh, svh], -1)[solvable]
        mean[solvable] = np.linalg.solve(normal[solvable], rhs[..., None])[:, 0, 0]
    return mean


def geodesic_distances(field: HeightField, source: np.ndarray) -> np.ndarray:
    """(rows, cols) shortest distances along the surface from the cell nearest `source` (inf where
    the surface does not connect to it, NaN where there is no surface)."""
    rows, cols = field.height.shape
    height = field.height.ravel()
    valid = np.isfinite(height)
    index = np.arange(rows * cols).reshape(rows, cols)
    start, end, length = [], [], []
    for du, dv in STENCIL:
        a = index[: rows - dv, max(0, -du) : cols - max(0, du)].ravel()
        b = a + dv * cols + du
        keep = valid[a] & valid[b]
        a, b = a[keep], b[keep]
        step = field.cell_mm * np.hypot(du, dv)
        rise = height[b] - height[a]
        keep = np.abs(rise) <= np.tan(np.radians(MAX_SLOPE_DEG)) * step
        for k in range(1, max(abs(du), dv)):  # the cells the step passes over: there, and near its line
            t = k / max(abs(du), dv)
            over = a + round(t * dv) * cols + round(t * du)
            keep &= valid[over] & (np.abs(height[over] - height[a] - t * rise) <= STRAIGHT_MM)
        start.append(a[keep])
        end.append(b[keep])
        length.append(np.hypot(step, rise[keep]))
    graph = coo_matrix((np.concatenate(length), (np.concatenate(start), np.concatenate(end))), shape=(rows * cols,) * 2)
    points = field.points().reshape(-1, 3)
    candidates = np.flatnonzero(valid)
    first = candidates[np.argmin(np.linalg.norm(points[candidates] - source, axis=1))]
    distance = dijkstra(graph.tocsr(), directed=False, indices=int(first)) + np.linalg.norm(points[first] - source)
    distance[~valid] = np.nan
    return distance.reshape(rows, cols)


def sample(field: HeightField, values: np.ndarray, points: np.ndarray) -> np.ndarray:
    """`values` (rows, cols) bilinearly at points projected onto the grid (NaN where any of the
    four cells around is empty or unreached)."""
    return map_coordinates(values, field.cell_of(points).T, order=1, mode="constant", cval=np.nan)
