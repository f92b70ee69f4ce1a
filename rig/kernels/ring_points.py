"""The ring samples' points from their cone roots (rig.pipeline.ring_triangulation and
rig.pipeline.ring_angles), compiled by numba: the root whose projector angle matches the decoded
angle, and the samples the fine angle places, each a sample at a time over a range of samples (one
pass, not a dozen array passes and gathers over every sample), the GIL released."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig.kernels import KERNEL


@njit(nogil=True, cache=True)
def _angle_error(root: float, theta: float, decoded: float) -> float:
    """|theta - decoded| wrapped to [0, pi] (as |np.angle(np.exp(1j (theta - decoded)))|); inf
    where the root is missing."""
    if not np.isfinite(root):
        return np.inf
    turn = theta - decoded
    return abs(math.atan2(math.sin(turn), math.cos(turn)))


@njit(**KERNEL)
def chosen_roots(
    roots: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    decoded: np.ndarray,
    rays: tuple[np.ndarray, np.ndarray],
    limits: tuple[float, float],
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    start: int,
    stop: int,
) -> None:
    """For samples [start, stop): the root (of roots = (s, theta, ds_dradius, cos_beta), each
    (M, 2)) whose projector angle is nearer the `decoded` angle, found where it is within
    limits[1] radians; its point and the other root's on the `rays` (origins, directions), its
    displacement per limits[0] pixels of radius error and its cos_beta (0 where undefined).
    out = (found, points, other, sigma, cos_beta)."""
    s, theta, ds_dradius, cos_beta = roots
    origins, directions = rays
    radius_sigma, max_error = limits
    found, points, other, sigma, cos_chosen = out
    for i in range(start, stop):
        first = _angle_error(s[i, 0], theta[i, 0], decoded[i])
        second = _angle_error(s[i, 1], theta[i, 1], decoded[i])
        k = 1 if second < first else 0  # np.argmin: the first of equals
        found[i] = min(first, second) <= max_error
        for j in range(3):
            points[i, j] = origins[i, j] + s[i, k] * directions[i, j]
            other[i, j] = origins[i, j] + s[i, 1 - k] * directions[i, j]
        sigma[i] = abs(ds_dradius[i, k]) * radius_sigma
        cos_chosen[i] = cos_beta[i, k] if not np.isnan(cos_beta[i, k]) else 0.0


@njit(**KERNEL)
def placed_by_angle(
    idx: np.ndarray,
    solution: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    roots: tuple[np.ndarray, np.ndarray],
    rays: tuple[np.ndarray, np.ndarray],
    limits: tuple[float, float],
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    start: int,
    stop: int,
) -> tuple[int, int]:
    """The samples idx[start:stop] placed by radius and fine angle (rig.pipeline.ring_angles
    .place_by_fine_angle): solution = (s, sigma_s, chi2, margin) per entry of idx, roots = the cone's
    (s, cos_beta) per sample, limits = (largest chi2, least margin). Each is found where its reading
    neither misfits nor is ambiguous; its point is on its ray at the solution, its rejected root the
    cone root farther from it unless both lie within 6 sigma, its cos_beta the nearer root's.
    out = (found, points, other, sigma, cos_beta), per sample. Returns the counts misfit and
    ambiguous."""
    s, sigma_s, chi2, margin = solution
    cone_s, cone_cos = roots
    origins, directions = rays
    max_chi2, min_margin = limits
    found, points, other, sigma, cos_beta = out
    misfits = ambiguous = 0
    for m in range(start, stop):
        i, at = idx[m], s[m]
        solvable = np.isfinite(at)
        misfit = solvable and chi2[m] > max_chi2
        unclear = solvable and not misfit and margin[m] < min_margin
        misfits += misfit
        ambiguous += unclear
        found[i] = solvable and not misfit and not unclear
        sigma[i] = sigma_s[m]
        near_0, near_1 = abs(cone_s[i, 0] - at), abs(cone_s[i, 1] - at)
        near_0 = near_0 if np.isfinite(near_0) else np.inf
        near_1 = near_1 if np.isfinite(near_1) else np.inf
        k = 1 if near_1 < near_0 else 0  # the nearer root (np.argmin: the first of equals)
        apart = abs(cone_s[i, 0] - cone_s[i, 1]) > 6 * sigma_s[m]
        for j in range(3):
            points[i, j] = origins[i, j] + at * directions[i, j]
            other[i, j] = origins[i, j] + cone_s[i, 1 - k] * directions[i, j] if apart else np.nan
        cos_beta[i] = cone_cos[i, k] if not np.isnan(cone_cos[i, k]) else 0.0
    return misfits, ambiguous
