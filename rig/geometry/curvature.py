"""Curvature of scanned surfaces and of curves on them.

Surfaces: a least-squares quadric z = f(x, y) in each point's local frame (the plane of its
neighbours within `radius_mm`, z along the normal that faces the viewer), principal curvatures from
the Weingarten map of that graph at the point. Noise in z is noise in the fitted coefficients only:
the curvatures are unbiased where the surface bends, while their magnitudes are biased upward where
it does not (a plane reads |kappa| about the noise of the fit, see `flat_noise`). Points are first
averaged on a voxel grid (a quarter of the radius): fewer fits, less noise, and a bias of about
kappa * voxel^2 / 12, negligible at the scales used here.

Curves: kappa(s) = |r' x r''| / |r'|^3 of the curve resampled by arc length and smoothed by a
Gaussian of `smooth_mm`.

Sign: positive where the surface bends away from its viewer-facing normal (a convex bump toward
the viewer, a sphere seen from outside), negative in a hollow.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import cKDTree

from rig.kernels import cell_keys
from rig.lazy import lazy_module
from rig.workers import batches, pool

curvature_kernels = lazy_module("rig.kernels.curvature")  # numba compiles on first use

# Neighbours at most per fit (of the voxel-averaged cloud): a disc of `radius_mm` holds about 50.
_MAX_NEIGHBOURS = 96

# A fit whose neighbours' centroid is further than this fraction of the radius from its centre is
# at the border of the scanned surface (a disc's half has its centroid at 0.42 of the radius).
_MAX_OFFSET = 0.25

# The least ratio of the neighbours' second to first spread (variance) across the tangent plane: a
# disc has 1, a band along one curve next to 0.
_MIN_SPREAD = 0.15

# The voxel grid's orientation: a fixed rotation that aligns no grid face with a world plane.
_GRID_TURN = np.linalg.qr(np.array([[0.8, 0.3, 0.52], [-0.35, 0.9, 0.27], [-0.45, -0.2, 0.87]]))[0]


@dataclass(frozen=True, eq=False)
class SurfaceCurvature:
    """Principal curvatures (1/mm) at `points` (the voxel-averaged cloud), k1 >= k2, with their
    directions, the viewer-facing unit normal, the rms residual of each fit and its neighbour count.
    `valid` marks fits with enough neighbours spread in two directions around the point (not at
    the border of the scanned surface)."""

    points: np.ndarray  # (M, 3)
    normals: np.ndarray  # (M, 3)
    k1: np.ndarray  # (M,)
    k2: np.ndarray
    dir1: np.ndarray  # (M, 3) unit tangent of k1
    dir2: np.ndarray
    residual_mm: np.ndarray  # (M,)
    neighbours: np.ndarray  # (M,) int
    valid: np.ndarray  # (M,) bool
    radius_mm: float

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, index: np.ndarray) -> SurfaceCurvature:
        """The curvatures at `index` (indices or a mask) only."""
        arrays = {f.name: getattr(self, f.name)[index] for f in dataclasses.fields(self) if f.name != "radius_mm"}
        return SurfaceCurvature(**arrays, radius_mm=self.radius_mm)

    @property
    def mean(self) -> np.ndarray:
        return 0.5 * (self.k1 + self.k2)

    @property
    def max_abs(self) -> np.ndarray:
        return np.maximum(np.abs(self.k1), np.abs(self.k2))

    def normal_curvature(self, directions: np.ndarray) -> np.ndarray:
        """Curvature of the normal section along each point's tangent `directions` (M, 3), Euler's
        formula k1 cos^2 + k2 sin^2 (directions need not be unit or tangent: they are projected)."""
        c1 = np.einsum("ij,ij->i", directions, self.dir1)
        c2 = np.einsum("ij,ij->i", directions, self.dir2)
        norm2 = np.maximum(c1**2 + c2**2, 1e-300)
        return (self.k1 * c1**2 + self.k2 * c2**2) / norm2


def voxel_average(points: np.ndarray, voxel_mm: float) -> np.ndarray:
    """The mean of the points in each occupied voxel of side `voxel_mm`. The grid is turned
    obliquely to the world axes: a plane lying on a voxel face (the bench plane z = 0 on an
    axis-aligned grid) would have its noise split between two layers of voxels, biasing both."""
    flat, _ = cell_keys(np.floor(points @ _GRID_TURN / voxel_mm).astype(np.int64))  # one integer per voxel
    _, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
    sums = np.column_stack([np.bincount(inverse, points[:, j], len(counts)) for j in range(3)])
    return sums / counts[:, None]


def principal_curvatures(
    points: np.ndarray,
    viewpoint: np.ndarray,
    radius_mm: float = 5.0,
    min_neighbours: int = 12,
    spacing_mm: float | None = None,
) -> SurfaceCurvature:
    """Principal curvatures of the surface sampled by `points` (N, 3), fitted on their average on a
    voxel grid of a quarter of `radius_mm`, at every voxel or (with `spacing_mm`) at the averages
    on a coarser grid; normals face `viewpoint` (the camera centre, mm). Raises ValueError when
    there are fewer than `min_neighbours` points."""
    points = np.asarray(points, float)
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) < min_neighbours:
        raise ValueError(f"curvature needs at least {min_neighbours} points, got {len(points)}")
    grid = voxel_average(points, radius_mm / 4.0)
    centres = grid if spacing_mm is None else voxel_average(grid, spacing_mm)
    distance, index = cKDTree(grid).query(centres, k=min(_MAX_NEIGHBOURS, len(grid)), distance_upper_bound=radius_mm)
    inside = np.isfinite(distance)
    index = np.where(inside, index, 0)
    count = inside.sum(axis=1)
    neighbours = (grid, np.ascontiguousarray(centres), np.ascontiguousarray(index, np.int64), inside)
    normal, e1, e2, flatness = _local_frames(neighbours, np.asarray(viewpoint, float))
    frames = np.ascontiguousarray(np.stack([e1, e2, normal], axis=1))
    size = len(centres)
    gram, right, along = np.empty((size, 6, 6)), np.empty((size, 6)), np.empty((size, 2))
    _each_centre(curvature_kernels.quadric_sums, (*neighbours, frames, gram, right, along), size)
    gram += 1e-9 * np.eye(6)
    coef = np.linalg.solve(gram, right[..., None])[..., 0]
    squares = np.empty(size)
    _each_centre(curvature_kernels.quadric_misfits, (*neighbours, frames, coef, squares), size)
    rms = np.sqrt(squares / np.maximum(count - 6, 1))
    k1, k2, d1, d2 = _weingarten(coef, e1, e2, normal)
    conditioned = np.linalg.cond(gram[:, :5, :5]) < 1e10
    # At the border of what was scanned the neighbours sit on one side: the fit extrapolates.
    offset = np.hypot(along[:, 0], along[:, 1]) / np.maximum(count, 1)
    valid = (count >= min_neighbours) & conditioned & np.isfinite(k1) & (offset < _MAX_OFFSET * radius_mm)
    valid &= flatness >= _MIN_SPREAD  # neighbours along one curve (a single ring) do not make a surface
    return SurfaceCurvature(centres, normal, k1, k2, d1, d2, rms, count, valid, radius_mm)


def _each_centre(kernel: Callable[..., None], arrays: tuple[np.ndarray, ...], size: int) -> None:
    """A compiled pass (rig.kernels.curvature) over the centres, a span of them per thread."""
    list(pool().map(lambda span: kernel(*arrays, *span), batches(size)))


def _local_frames(
    neighbours: tuple[np.ndarray, ...], viewpoint: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Normal (the neighbours' least-variance direction, toward the viewpoint), two tangents, and
    how evenly the neighbours spread across the tangent plane (second / first variance);
    neighbours: the grid, the centres, each one's neighbours in the grid and which are in reach."""
    size = len(neighbours[1])
    mean, cov = np.empty((size, 3)), np.empty((size, 3, 3))
    _each_centre(curvature_kernels.neighbour_spread, (*neighbours, mean, cov), size)
    values, vectors = np.linalg.eigh(cov)
    spread_ratio = values[:, 1] / np.maximum(values[:, 2], 1e-300)
    normal = vectors[:, :, 0]
    e1 = vectors[:, :, 2]
    flip = np.einsum("ij,ij->i", normal, viewpoint - neighbours[1]) < 0
    normal[flip] *= -1
    e2 = np.cross(normal, e1)
    return normal, e1, e2, spread_ratio


def _weingarten(
    coef: np.ndarray, e1: np.ndarray, e2: np.ndarray, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Principal curvatures and 3D directions of z = a x^2 + b xy + c y^2 + d x + e y + f at x = y = 0."""
    a, b, c, d, e = (coef[:, i] for i in range(5))
    w = np.sqrt(1.0 + d * d + e * e)
    first = np.stack([np.stack([1 + d * d, d * e], -1), np.stack([d * e, 1 + e * e], -1)], -2)
    second = np.stack([np.stack([2 * a, b], -1), np.stack([b, 2 * c], -1)], -2) / w[:, None, None]
    shape = -np.linalg.solve(first, second)  # minus: convex toward the normal reads positive
    values, vectors = np.linalg.eig(shape)
    values, vectors = values.real, vectors.real
    order = np.argsort(-values, axis=1)
    rows = np.arange(len(values))[:, None]
    values = values[rows, order]
    vectors = np.take_along_axis(vectors, order[:, None, :], axis=2)
    tx = e1 + d[:, None] * normal  # the graph's tangent vectors at the origin
    ty = e2 + e[:, None] * normal
    directions = []
    for k in range(2):
        v = vectors[:, 0, k, None] * tx + vectors[:, 1, k, None] * ty
        directions.append(v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None])
    return values[:, 0], values[:, 1], directions[0], directions[1]


def flat_noise(curvature: SurfaceCurvature) -> np.ndarray:
    """The curvature a plane would read with each fit's residual noise: the standard error of the
    fitted second derivative, about 8 residual / (sqrt(n) radius^2) for n points spread evenly
    over a disc (what a flat surface shows as |kappa|)."""
    n = np.maximum(curvature.neighbours, 1)
    return curvature.residual_mm * 8.0 / np.sqrt(n) / curvature.radius_mm**2


def curve_curvature(
    points: np.ndarray, step_mm: float = 0.5, smooth_mm: float = 2.0, closed: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Arc length s and curvature kappa(s) (1/mm) of the polyline `points` (n, 3, in order):
    resampled every `step_mm`, smoothed by a Gaussian of `smooth_mm`. Raises ValueError for a curve
    shorter than five steps."""
    points = np.asarray(points, float)
    if closed:
        points = np.vstack([points, points[:1]])
    chord = np.linalg.norm(np.diff(points, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(chord)])
    if arc[-1] < 5 * step_mm:
        raise ValueError(f"a curve of {arc[-1]:.3g} mm is too short for curvature at {step_mm} mm steps")
    keep = np.concatenate([[True], chord > 0])
    arc, points = arc[keep], points[keep]
    count = int(arc[-1] / step_mm) + (0 if closed else 1)
    s = np.arange(count) * (arc[-1] / count if closed else step_mm)
    resampled = np.column_stack([np.interp(s, arc, points[:, j]) for j in range(3)])
    mode = "wrap" if closed else "nearest"
    sigma = smooth_mm / (s[1] - s[0])
    smooth = gaussian_filter1d(resampled, sigma, axis=0, mode=mode)
    spacing = s[1] - s[0]
    if closed:
        first = (np.roll(smooth, -1, 0) - np.roll(smooth, 1, 0)) / (2 * spacing)
        second = (np.roll(smooth, -1, 0) - 2 * smooth + np.roll(smooth, 1, 0)) / spacing**2
    else:
        first = np.gradient(smooth, spacing, axis=0)
        second = np.gradient(first, spacing, axis=0)
    speed = np.maximum(np.linalg.norm(first, axis=1), 1e-12)
    kappa = np.linalg.norm(np.cross(first, second), axis=1) / speed**3
    return s, kappa
