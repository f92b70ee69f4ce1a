"""Ring samples read with the fine angular code: depth from the ring's radius and its polar angle
together, each weighted by how well it fixes the point.

A camera ray's image in the projector is its epipolar line. The ring's radius fixes where on that
line the point is only where the line crosses the ring steeply; where the ring runs along the line
(the two wedges of every ring the radius alone leaves empty) the angle does. The fine code gives the
angle modulo one of its periods, so each sample has branches theta_j = (phi + 2 pi j) / M: the ray
meets the projector's half-plane of each branch angle at one point (ray to ray). The branches near
the coarse angle are scored against the ring's radius and the coarse angle; the best is refined by
Gauss-Newton on the radius and fine-angle residuals, which weights each coordinate by its
conditioning. A sample whose best branch misfits (a mixed pixel on a depth edge) is rejected, from
`chi2`. One whose second best fits nearly as well (an ambiguous period, from `margin`: where the
ring runs along the epipolar line only the coarse angle picks the period) is read again with the
angle its ring's placed neighbours predict, and rejected only if it stays ambiguous.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rig.geometry import CameraModel, ConeHits, affine_image, ray_half_plane
from rig.lazy import lazy_module
from rig.patterns import RingSamples
from rig.pipeline.ring_neighbours import neighbour_angles, wrap_angle
from rig.workers import batches, pool

ring_kernels = lazy_module("rig.kernels.rings")  # numba compiles on first use: not for --help
point_kernels = lazy_module("rig.kernels.ring_points")

# A sample is rejected when its best reading misfits the decoded radius
# and angles by more than this chi-square (a mixed pixel on a depth edge, read between two surfaces),
# or when another period of the fine code fits within MIN_BRANCH_MARGIN of it (ambiguous).
MAX_ANGLE_CHI2 = 25.0
MIN_BRANCH_MARGIN = 9.0

# Branches of the fine code are searched this far (radians) on either side of the coarse angle.
BRANCH_WINDOW_RAD = 0.3
# Assumed error of the coarse angular code (radians), for scoring branches.
COARSE_SIGMA_RAD = 0.05
# An ambiguous sample is read again with the angle its ring's neighbours predict (the nearest placed
# samples of its ring: rig.pipeline.ring_neighbours), trusted when their plane fits within
# NEIGHBOUR_SCATTER_PERIODS of a fine period and taken as that good to NEIGHBOUR_SIGMA_PERIODS (a
# leave-one-out test on a face misses by 0.9 % of a period at p99.9).
NEIGHBOUR_SCATTER_PERIODS = 0.05
NEIGHBOUR_SIGMA_PERIODS = 0.05
# Gauss-Newton iterations from a branch's ray-to-ray point.
_ITERATIONS = 3
_STEP_MM = 1e-3  # for numerical derivatives along the ray


@dataclass(frozen=True, eq=False)
class AngleSolution:
    """Per sample: the ray parameter of the best branch (NaN if no branch meets the ray), its
    standard deviation, the best branch's misfit and how much worse the second best fits."""

    s: np.ndarray
    sigma_s: np.ndarray
    chi2: np.ndarray
    margin: np.ndarray  # chi2 of the second-best branch minus chi2 of the best; inf if none


class _Rays:
    """Rays (n, 3) seen in the projector image: radius and angle about the rings' centre of the point
    at ray parameter s, and their slopes along the ray. Without distortion the image point is
    (a + s b)[:2] / (a + s b)[2] for per-ray vectors a, b (rig.geometry.cone.affine_image): closed
    forms; with it, the full projection and central differences."""

    def __init__(
        self, projector: CameraModel, origins: np.ndarray, directions: np.ndarray, center: tuple[float, float]
    ) -> None:
        self.projector, self.origins, self.directions, self.center = projector, origins, directions, center
        self.affine: tuple[np.ndarray, ...] | None = None
        if not projector.has_distortion:
            alpha, beta = affine_image(projector, origins, directions)
            u0, v0 = center
            self.affine = tuple(  # centred, as (n, 1) columns for broadcasting against (n, k)
                column[:, None]
                for column in (
                    alpha[:, 0] - u0 * alpha[:, 2],
                    alpha[:, 1] - v0 * alpha[:, 2],
                    alpha[:, 2],
                    beta[:, 0] - u0 * beta[:, 2],
                    beta[:, 1] - v0 * beta[:, 2],
                    beta[:, 2],
                )
            )

    def polar(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Projector radius and angle about the centre of the points at ray parameters s (n, k)."""
        if self.affine is not None:
            a0, a1, a2, b0, b1, b2 = self.affine
            w = a2 + s * b2
            x, y = (a0 + s * b0) / w, (a1 + s * b1) / w
            return np.hypot(x, y), np.arctan2(y, x)
        points = self.origins[:, None, :] + s[..., None] * self.directions[:, None, :]
        uv, _ = self.projector.project(points.reshape(-1, 3))
        du, dv = uv[:, 0] - self.center[0], uv[:, 1] - self.center[1]
        return np.hypot(du, dv).reshape(s.shape), np.arctan2(dv, du).reshape(s.shape)

    def slopes(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Radius, angle, d radius / ds and d angle / ds at ray parameters s (n, k)."""
        if self.affine is not None:
            a0, a1, a2, b0, b1, b2 = self.affine
            w = a2 + s * b2
            x, y = (a0 + s * b0) / w, (a1 + s * b1) / w
            dx, dy = (b0 * a2 - a0 * b2) / (w * w), (b1 * a2 - a1 * b2) / (w * w)
            rho = np.hypot(x, y)
            return rho, np.arctan2(y, x), (x * dx + y * dy) / rho, (x * dy - y * dx) / (rho * rho)
        rho, angle = self.polar(s)
        (rho_p, angle_p), (rho_m, angle_m) = self.polar(s + _STEP_MM), self.polar(s - _STEP_MM)
        return rho, angle, (rho_p - rho_m) / (2 * _STEP_MM), wrap_angle(angle_p - angle_m) / (2 * _STEP_MM)


def solve_ring_angles(
    projector: CameraModel,
    origins: np.ndarray,
    directions: np.ndarray,
    radius: np.ndarray,
    coarse_theta: np.ndarray,
    fine_phase: np.ndarray,
    fine_periods: np.ndarray,
    center: tuple[float, float],
    radius_sigma_px: float,
    tangential_sigma_px: float,
    chunk: int = 4096,
    coarse_sigma: float | np.ndarray = COARSE_SIGMA_RAD,
    terms: np.ndarray | None = None,
) -> AngleSolution:
    """Best point along each ray (M, 3) on its ring (`radius`, pixels) agreeing with the decoded
    angles: `coarse_theta` (radians, absolute, with error `coarse_sigma`, one or per ray) and
    `fine_phase` (wrapped, of `fine_periods` periods per revolution). `terms`: the rays' images
    about the centre where known (ConeHits.terms), for a projector without distortion."""
    n = len(radius)
    sigma = np.broadcast_to(np.asarray(coarse_sigma, dtype=np.float64), (n,))
    if not projector.has_distortion:
        if terms is None:
            affine = _Rays(projector, origins, directions, center).affine
            assert affine is not None
            terms = np.column_stack(affine)
        per_sample = (radius, coarse_theta, fine_phase, fine_periods, sigma)
        return _solved_compiled(terms, per_sample, (radius_sigma_px, tangential_sigma_px))
    out = [np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.inf), np.full(n, np.inf)]
    for start in range(0, n, chunk):
        part = slice(start, min(n, start + chunk))
        rays = _Rays(projector, origins[part], directions[part], center)
        solved = _solve_chunk(
            rays,
            radius[part],
            coarse_theta[part],
            fine_phase[part],
            fine_periods[part],
            radius_sigma_px,
            tangential_sigma_px,
            sigma[part],
        )
        for array, value in zip(out, solved, strict=True):
            array[part] = value
    return AngleSolution(*out)


def _solved_compiled(
    terms: np.ndarray, per_sample: tuple[np.ndarray, ...], sigmas: tuple[float, float]
) -> AngleSolution:
    """solve_ring_angles for a projector without distortion (`terms`: the rays' images about the
    centre), a sample at a time in compiled code (rig.kernels.rings.solve_angles): the same
    branches, scores and refinement as _solve_chunk."""
    terms = np.ascontiguousarray(terms, dtype=np.float64)
    radius, coarse, phase, periods, sigma = (np.ascontiguousarray(a, dtype=np.float64) for a in per_sample)
    out = np.empty((4, len(radius)))  # a row per field: each one contiguous
    constants = (BRANCH_WINDOW_RAD, (float(sigmas[0]), float(sigmas[1])), _ITERATIONS)
    list(
        pool().map(
            lambda span: ring_kernels.solve_angles(
                terms, radius, coarse, phase, periods, sigma, *constants, out, *span
            ),
            batches(len(radius)),
        )
    )
    return AngleSolution(*out)


def _solve_chunk(
    rays: _Rays,
    radius: np.ndarray,
    coarse: np.ndarray,
    phase: np.ndarray,
    periods: np.ndarray,
    radius_sigma: float,
    tangential_sigma: float,
    coarse_sigma: np.ndarray,
) -> tuple[np.ndarray, ...]:
    periods_f = periods.astype(np.float64)
    window = np.minimum(BRANCH_WINDOW_RAD, 6.0 * coarse_sigma)
    lo = np.ceil((periods_f * (coarse - window) - phase) / (2 * np.pi))
    hi = np.floor((periods_f * (coarse + window) - phase) / (2 * np.pi))
    width = int(np.max(hi - lo, initial=0)) + 1
    branch = lo[:, None] + np.arange(width)[None, :]
    theta = (phase[:, None] + 2 * np.pi * branch) / periods_f[:, None]
    s = ray_half_plane(rays.projector, rays.origins, rays.directions, theta, rays.center)
    s[branch > hi[:, None]] = np.nan
    rho, _ = rays.polar(np.nan_to_num(s, nan=1.0))
    coarse_misfit = (wrap_angle(theta - coarse[:, None]) / coarse_sigma[:, None]) ** 2
    score = ((rho - radius[:, None]) / radius_sigma) ** 2 + coarse_misfit
    score[~np.isfinite(s)] = np.inf
    # the two best branches, refined, then compared on their full misfit
    order = np.argsort(score, axis=1)[:, :2]
    if order.shape[1] == 1:
        order = np.column_stack([order, order])
    rows = np.arange(len(radius))[:, None]
    best_s, best_theta = s[rows, order], theta[rows, order]
    refined, sigma, chi2 = _refine(rays, best_s, best_theta, radius, radius_sigma, tangential_sigma)
    chi2 = chi2 + (wrap_angle(best_theta - coarse[:, None]) / coarse_sigma[:, None]) ** 2
    chi2[~np.isfinite(refined)] = np.inf
    if width == 1:
        chi2[:, 1] = np.inf
    first = np.argmin(chi2, axis=1)
    r = rows[:, 0]
    with np.errstate(invalid="ignore"):  # inf - inf where no branch fits: no margin to speak of
        margin = chi2[r, 1 - first] - chi2[r, first]
    return refined[r, first], sigma[r, first], chi2[r, first], np.nan_to_num(margin, nan=np.inf)


def _refine(
    rays: _Rays, s: np.ndarray, theta: np.ndarray, radius: np.ndarray, radius_sigma: float, tangential_sigma: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Newton on r = [(rho - R) / sigma_R, R (angle - theta) / sigma_t] along each ray from
    `s` (n, k); the refined s, its standard deviation and the misfit |r|^2."""
    s = np.nan_to_num(s, nan=np.nan).copy()
    bad = ~np.isfinite(s)
    s[bad] = 1.0
    R = radius[:, None]

    information = np.ones_like(s)
    for iteration in range(_ITERATIONS + 1):
        rho, angle, d_rho, d_angle = rays.slopes(s)
        r1, r2 = (rho - R) / radius_sigma, R * wrap_angle(angle - theta) / tangential_sigma
        j1, j2 = d_rho / radius_sigma, R * d_angle / tangential_sigma
        information = j1 * j1 + j2 * j2
        if iteration < _ITERATIONS:  # the last pass only measures the misfit and the information
            s = s - (j1 * r1 + j2 * r2) / np.maximum(information, 1e-300)
    sigma = 1.0 / np.sqrt(np.maximum(information, 1e-300))
    s[bad | (s <= 0)] = np.nan
    return s, sigma, r1 * r1 + r2 * r2


@dataclass(frozen=True, eq=False)
class Placed:
    """Per-sample results of triangulation, updated in place where the fine angle places a sample."""

    found: np.ndarray
    points: np.ndarray
    other: np.ndarray
    sigma: np.ndarray
    cos_beta: np.ndarray


def place_by_fine_angle(
    projector: CameraModel,
    origins: np.ndarray,
    directions: np.ndarray,
    samples: RingSamples,
    hits: ConeHits,
    roots: np.ndarray,
    idx: np.ndarray,
    placed: Placed,
) -> dict[str, int]:
    """Place the samples `idx` by radius and fine angle together (rig.pipeline.ring_angles); the cone
    `roots` (M, 2) only name the rejected root. Returns the counts of what it rejected and fixed."""
    assert samples.fine_phase is not None and samples.fine_periods is not None

    def solve(which: np.ndarray, coarse: np.ndarray, sigma: float | np.ndarray = COARSE_SIGMA_RAD) -> AngleSolution:
        return solve_ring_angles(
            projector,
            np.take(origins, which, axis=0),  # np.take: a fancy index of a 2-D array is slower
            np.take(directions, which, axis=0),
            samples.radius_px[which],
            coarse,
            samples.fine_phase[which],
            samples.fine_periods[which],
            samples.center_px,
            samples.radius_sigma_px,
            samples.tangential_sigma_px,
            coarse_sigma=sigma,
            terms=None if projector.has_distortion else np.take(hits.terms, which, axis=0),
        )

    solution = solve(idx, samples.theta[idx])
    resolved = _resolve_from_neighbours(projector, origins, directions, samples, idx, solution, solve)
    # The cone root the solution did not take is the rejected root; where the roots lie within a few
    # sigma of each other (the ring along the epipolar line) there is no root to reject.
    arrays = (
        idx,
        (solution.s, solution.sigma_s, solution.chi2, solution.margin),
        (roots, hits.cos_beta),
        (origins, np.ascontiguousarray(directions, np.float64)),
        (MAX_ANGLE_CHI2, MIN_BRANCH_MARGIN),
        (placed.found, placed.points, placed.other, placed.sigma, placed.cos_beta),
    )
    counted = list(pool().map(lambda span: point_kernels.placed_by_angle(*arrays, *span), batches(len(idx))))
    misfit, ambiguous = sum(c[0] for c in counted), sum(c[1] for c in counted)
    fine = placed.found[idx] & (placed.cos_beta[idx] < samples.min_cos_beta)
    return {
        "rejected_angle_misfit": misfit,
        "rejected_angle_ambiguous": ambiguous,
        "resolved_by_neighbours": resolved,
        "fixed_by_angle": int(fine.sum()),
    }


def _resolve_from_neighbours(
    projector: CameraModel,
    origins: np.ndarray,
    directions: np.ndarray,
    samples: RingSamples,
    idx: np.ndarray,
    solution: AngleSolution,
    solve: Callable[[np.ndarray, np.ndarray, np.ndarray], AngleSolution],
) -> int:
    """Samples whose fine-code period the coarse angle leaves ambiguous, read again with the angle
    their ring's placed neighbours predict (far finer than the coarse code: a plane fitted to the
    neighbours' angles over the image). Where the ring runs along the epipolar line the radius cannot
    pick the period and the coarse code's noise is half a period, so without this whole stretches
    of ring go missing. `solution` (of the samples `idx`) is updated in place; returns how many
    were resolved."""
    solvable = np.isfinite(solution.s) & (solution.chi2 <= MAX_ANGLE_CHI2)
    clear = solution.margin >= MIN_BRANCH_MARGIN
    placed, ambiguous = solvable & clear, solvable & ~clear
    if not ambiguous.any() or not placed.any():
        return 0
    at, s_placed = idx[placed], solution.s[placed]

    def angle_of(which: np.ndarray) -> np.ndarray:  # the placed samples' projector angles
        points = np.take(origins, at[which], axis=0) + s_placed[which, None] * np.take(directions, at[which], axis=0)
        uv, _ = projector.project(points)
        return np.arctan2(uv[:, 1] - samples.center_px[1], uv[:, 0] - samples.center_px[0])

    xy, ring = np.take(samples.camera_xy, idx, axis=0), samples.ring[idx]
    wanted = np.flatnonzero(ambiguous)
    predicted, scatter = neighbour_angles(xy[placed], ring[placed], angle_of, xy[wanted], ring[wanted])
    period = 2 * np.pi / samples.fine_periods[idx[wanted]]
    trusted = np.isfinite(predicted) & (scatter <= NEIGHBOUR_SCATTER_PERIODS * period)
    trusted &= np.abs(wrap_angle(predicted - samples.theta[idx[wanted]])) <= 3 * COARSE_SIGMA_RAD
    wanted, predicted, period = wanted[trusted], predicted[trusted], period[trusted]
    if len(wanted) == 0:
        return 0
    again = solve(idx[wanted], predicted, NEIGHBOUR_SIGMA_PERIODS * period)
    fixed = np.isfinite(again.s) & (again.chi2 <= MAX_ANGLE_CHI2) & (again.margin >= MIN_BRANCH_MARGIN)
    for mine, theirs in zip(
        (solution.s, solution.sigma_s, solution.chi2, solution.margin),
        (again.s, again.sigma_s, again.chi2, again.margin),
        strict=True,
    ):
        mine[wanted[fixed]] = theirs[fixed]
    return int(fixed.sum())
