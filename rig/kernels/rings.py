"""The ring samples' reading by radius and fine angle together (rig.pipeline.ring_angles), compiled
by numba for a projector without distortion: one sample at a time, its few branches of the fine
code scored and the best two refined, with no (samples, branches) arrays. Each call takes a range
of samples, the GIL released, so rig.workers runs ranges on its threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(nogil=True, cache=True, inline="always")
def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


@njit(nogil=True, cache=True, inline="always")
def _half_plane(terms: np.ndarray, i: int, theta: float) -> float:
    """rig.geometry.ray_half_plane for ray i (its centred affine image `terms[i]`: a0, a1, a2, b0,
    b1, b2) and one angle; NaN where the ray meets only the other half, or behind either device."""
    a0, a1, a2, b0, b1, b2 = terms[i, 0], terms[i, 1], terms[i, 2], terms[i, 3], terms[i, 4], terms[i, 5]
    sin, cos = math.sin(theta), math.cos(theta)
    below = b0 * sin - b1 * cos
    if below == 0:
        return np.nan
    s = -(a0 * sin - a1 * cos) / below
    along = (a0 + s * b0) * cos + (a1 + s * b1) * sin
    if not (s > 0 and a2 + s * b2 > 0 and along > 0 and np.isfinite(s)):
        return np.nan
    return s


@njit(nogil=True, cache=True, inline="always")
def _slopes(terms: np.ndarray, i: int, s: float) -> tuple[float, float, float, float]:
    """Projector radius and angle about the centre of ray i's point at s, and their slopes in s."""
    a0, a1, a2, b0, b1, b2 = terms[i, 0], terms[i, 1], terms[i, 2], terms[i, 3], terms[i, 4], terms[i, 5]
    w = a2 + s * b2
    x, y = (a0 + s * b0) / w, (a1 + s * b1) / w
    dx, dy = (b0 * a2 - a0 * b2) / (w * w), (b1 * a2 - a1 * b2) / (w * w)
    rho = math.hypot(x, y)
    return rho, math.atan2(y, x), (x * dx + y * dy) / rho, (x * dy - y * dx) / (rho * rho)


@njit(nogil=True, cache=True)
def _refine(
    terms: np.ndarray, i: int, s: float, theta: float, radius: float, sigmas: tuple[float, float], iterations: int
) -> tuple[float, float, float]:
    """Gauss-Newton on [(rho - R) / sigma_R, R (angle - theta) / sigma_t] along ray i from s: the
    refined s (NaN if it fails), its standard deviation and the misfit."""
    radius_sigma, tangential_sigma = sigmas
    bad = not np.isfinite(s)
    s = 1.0 if bad else s
    information, r1, r2 = 1.0, 0.0, 0.0
    for iteration in range(iterations + 1):
        rho, angle, d_rho, d_angle = _slopes(terms, i, s)
        r1, r2 = (rho - radius) / radius_sigma, radius * _wrap(angle - theta) / tangential_sigma
        j1, j2 = d_rho / radius_sigma, radius * d_angle / tangential_sigma
        information = j1 * j1 + j2 * j2
        if iteration < iterations:  # the last pass only measures the misfit and the information
            s = s - (j1 * r1 + j2 * r2) / max(information, 1e-300)
    sigma = 1.0 / math.sqrt(max(information, 1e-300))
    if bad or not s > 0:
        s = np.nan
    return s, sigma, r1 * r1 + r2 * r2


@njit(**KERNEL)
def solve_angles(
    terms: np.ndarray,
    radius: np.ndarray,
    coarse: np.ndarray,
    phase: np.ndarray,
    periods: np.ndarray,
    coarse_sigma: np.ndarray,
    window: float,
    sigmas: tuple[float, float],
    iterations: int,
    out: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.ring_angles._solve_chunk for samples[start:stop]: the branches of the fine code
    within min(`window`, 6 coarse sigma) of the coarse angle scored on radius and coarse angle, the
    best two refined and compared on their full misfit. out[i] = (s, sigma_s, chi2, margin)."""
    two_pi = 2 * math.pi
    for i in range(start, stop):
        m, sc = np.float64(periods[i]), coarse_sigma[i]
        reach = min(window, 6.0 * sc)
        lo = math.ceil((m * (coarse[i] - reach) - phase[i]) / two_pi)
        hi = math.floor((m * (coarse[i] + reach) - phase[i]) / two_pi)
        best = (np.inf, np.nan, 0.0)  # (score, s, theta) of the best branch, then the second
        second = (np.inf, np.nan, 0.0)
        for branch in range(int(lo), int(hi) + 1):
            theta = (phase[i] + two_pi * branch) / m
            s = _half_plane(terms, i, theta)
            if not np.isfinite(s):
                continue
            rho = _slopes(terms, i, s)[0]
            score = ((rho - radius[i]) / sigmas[0]) ** 2 + (_wrap(theta - coarse[i]) / sc) ** 2
            if score < best[0]:
                best, second = (score, s, theta), best
            elif score < second[0]:
                second = (score, s, theta)
        chi2 = np.empty(2)
        solved = np.empty((2, 2))
        for k, (score, s, theta) in enumerate((best, second)):
            refined, sigma, misfit = _refine(terms, i, s, theta, radius[i], sigmas, iterations)
            misfit += (_wrap(theta - coarse[i]) / sc) ** 2
            chi2[k] = misfit if np.isfinite(refined) and np.isfinite(score) else np.inf
            solved[k, 0], solved[k, 1] = refined, sigma
        first = 0 if chi2[0] <= chi2[1] else 1
        margin = chi2[1 - first] - chi2[first]
        out[i, 0], out[i, 1], out[i, 2] = solved[first, 0], solved[first, 1], chi2[first]
        out[i, 3] = margin if np.isfinite(margin) or margin > 0 else np.inf
