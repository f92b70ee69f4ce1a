"""The ring samples' reading by radius and fine angle together (rig.pipeline.ring_angles), compiled
by numba for a projector without distortion: one sample at a time, its branches of the fine code
(a dozen on the default bench) scored with one angle turned from branch to branch (decision 0046)
and the best two refined, with no (samples, branches) arrays. Each call takes a range of samples,
the GIL released, so rig.workers runs ranges on its threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig.kernels import KERNEL
from rig.kernels.cells import Cells
from rig.kernels.phase import atan2


@njit(nogil=True, cache=True, inline="always")
def _wrap(angle: float) -> float:
    """The angle in [-pi, pi): by floor, not Python's float modulo (fmod, many times slower)."""
    return angle - 2 * math.pi * math.floor((angle + math.pi) / (2 * math.pi))


@njit(nogil=True, cache=True, inline="always")
def _half_plane(terms: np.ndarray, i: int, theta: float) -> float:
    """rig.geometry.ray_half_plane for ray i (its centred affine image `terms[i]`: a0, a1, a2, b0,
    b1, b2) and one angle; NaN where the ray meets only the other half, or behind either device."""
    return _met(terms, i, math.sin(theta), math.cos(theta))


@njit(nogil=True, cache=True, inline="always")
def _met(terms: np.ndarray, i: int, sin: float, cos: float) -> float:
    """_half_plane at the angle whose sine and cosine are given."""
    a0, a1, a2, b0, b1, b2 = terms[i, 0], terms[i, 1], terms[i, 2], terms[i, 3], terms[i, 4], terms[i, 5]
    below = b0 * sin - b1 * cos
    if below == 0:
        return np.nan
    s = -(a0 * sin - a1 * cos) / below
    along = (a0 + s * b0) * cos + (a1 + s * b1) * sin
    if not (s > 0 and a2 + s * b2 > 0 and along > 0 and np.isfinite(s)):
        return np.nan
    return s


@njit(nogil=True, cache=True, inline="always")
def _radius(terms: np.ndarray, i: int, s: float) -> float:
    """Projector radius about the centre of ray i's point at s, for a branch's score: a square root,
    not hypot, whose care for overflow radii never need (decision 0046)."""
    w = terms[i, 2] + s * terms[i, 5]
    x, y = (terms[i, 0] + s * terms[i, 3]) / w, (terms[i, 1] + s * terms[i, 4]) / w
    return math.sqrt(x * x + y * y)


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
    best two refined and compared on their full misfit. out[:, i] = (s, sigma_s, chi2, margin).
    The scores only choose the two (_best_two, decision 0046); the two chosen are met again exactly
    (_half_plane) before they are refined."""
    two_pi = 2 * math.pi
    for i in range(start, stop):
        m, sc = np.float64(periods[i]), coarse_sigma[i]
        reach = min(window, 6.0 * sc)
        lo = math.ceil((m * (coarse[i] - reach) - phase[i]) / two_pi)
        hi = math.floor((m * (coarse[i] + reach) - phase[i]) / two_pi)
        decoded = (phase[i], m, coarse[i], sc)
        chosen = _best_two(terms, i, (lo, hi), decoded, radius[i], sigmas[0])
        best_score, best_theta, second_score, second_theta = chosen
        best_s = _half_plane(terms, i, best_theta) if np.isfinite(best_score) else np.nan
        second_s = _half_plane(terms, i, second_theta) if np.isfinite(second_score) else np.nan
        angles = (radius[i], coarse[i], sc)
        s0, sigma0, chi0 = _refined(terms, i, (best_score, best_s, best_theta), angles, sigmas, iterations)
        s1, sigma1, chi1 = _refined(terms, i, (second_score, second_s, second_theta), angles, sigmas, iterations)
        if chi0 <= chi1:
            out[0, i], out[1, i], out[2, i], margin = s0, sigma0, chi0, chi1 - chi0
        else:
            out[0, i], out[1, i], out[2, i], margin = s1, sigma1, chi1, chi0 - chi1
        out[3, i] = margin if np.isfinite(margin) or margin > 0 else np.inf


@njit(nogil=True, cache=True, inline="always")
def _best_two(
    terms: np.ndarray,
    i: int,
    branches: tuple[int, int],
    decoded: tuple[float, float, float, float],
    radius: float,
    radius_sigma: float,
) -> tuple[float, float, float, float]:
    """(score, theta) of the best of ray i's fine-code branches `branches` (lo, hi: both counted)
    and of the second (inf, 0 where there is none); decoded: the sample's fine phase, periods,
    coarse angle and that angle's sigma. A branch the ray does not meet is missing (_met). Each
    branch's sine and cosine are the last one's turned by a period rather than made anew (a sample
    has a dozen branches on the default bench; with _radius's square root, 46.5 -> 35.3 ms on one
    thread, decision 0046): to 1e-15 of the exact ones, enough to choose by; the caller meets the
    two chosen again exactly."""
    lo, hi = branches
    phase, periods, coarse, coarse_sigma = decoded
    best_score, best_theta, second_score, second_theta = np.inf, 0.0, np.inf, 0.0
    two_pi = 2 * math.pi
    first = (phase + two_pi * lo) / periods
    sin, cos = math.sin(first), math.cos(first)
    turn_sin, turn_cos = math.sin(two_pi / periods), math.cos(two_pi / periods)
    for branch in range(lo, hi + 1):
        theta = (phase + two_pi * branch) / periods
        s = _met(terms, i, sin, cos)
        if np.isfinite(s):
            off_ring = (_radius(terms, i, s) - radius) / radius_sigma
            score = off_ring**2 + (_wrap(theta - coarse) / coarse_sigma) ** 2
            if score < best_score:
                second_score, second_theta = best_score, best_theta
                best_score, best_theta = score, theta
            elif score < second_score:
                second_score, second_theta = score, theta
        sin, cos = sin * turn_cos + cos * turn_sin, cos * turn_cos - sin * turn_sin
    return best_score, best_theta, second_score, second_theta


@njit(nogil=True, cache=True, inline="always")
def _refined(
    terms: np.ndarray,
    i: int,
    branch: tuple[float, float, float],
    decoded: tuple[float, float, float],
    sigmas: tuple[float, float],
    iterations: int,
) -> tuple[float, float, float]:
    """A scored branch (score, s, theta) refined: its s, sigma and chi-square with the coarse angle's
    misfit (infinite where the branch is missing or the refinement fails); decoded: the sample's
    radius, coarse angle and the coarse angle's sigma."""
    score, s, theta = branch
    radius, coarse, coarse_sigma = decoded
    refined, sigma, misfit = _refine(terms, i, s, theta, radius, sigmas, iterations)
    misfit += (_wrap(theta - coarse) / coarse_sigma) ** 2
    return refined, sigma, misfit if np.isfinite(refined) and np.isfinite(score) else np.inf


@njit(**KERNEL)
def along_support(
    xy: np.ndarray,
    ring: np.ndarray,
    depth: np.ndarray,
    cells: Cells,
    limits: tuple[float, float],
    support: np.ndarray,
    offset: np.ndarray,
    reach_sum: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """For points [start:stop], the samples of their own ring within `reach` pixels (limits:
    reach, max_jump; cells: rig.kernels.cells.sample_cells of side `reach`) whose depth is within
    `max_jump`: how many (`support`), the length of the sum of their offsets in the image (`offset`)
    and the sum of their distances (`reach_sum`)."""
    order, starts, x0, y0, nx, ny, _ = cells
    reach, max_jump = limits
    for i in range(start, stop):
        cx, cy = int((xy[i, 0] - x0) / reach), int((xy[i, 1] - y0) / reach)
        count, sx, sy, total = 0, 0.0, 0.0, 0.0
        for gy in range(max(cy - 1, 0), min(cy + 1, ny - 1) + 1):
            for gx in range(max(cx - 1, 0), min(cx + 1, nx - 1) + 1):
                c = gy * nx + gx
                for j in range(starts[c], starts[c + 1]):
                    q = order[j]
                    if q == i or ring[q] != ring[i] or abs(depth[q] - depth[i]) > max_jump:
                        continue
                    dx, dy = xy[q, 0] - xy[i, 0], xy[q, 1] - xy[i, 1]
                    d = math.sqrt(dx * dx + dy * dy)
                    if d <= reach:
                        count += 1
                        sx += dx
                        sy += dy
                        total += d
        support[i], offset[i], reach_sum[i] = count, math.sqrt(sx * sx + sy * sy), total


@njit(**KERNEL)
def ring_bands(
    read: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    sums: tuple[np.ndarray, np.ndarray],
    thresholds: tuple[float, float],
    annulus: np.ndarray,
    angle: np.ndarray,
    top: int,
    bottom: int,
) -> None:
    """rig.patterns.rings' bands for rows [top, bottom): `annulus` (int16) from the zone and the
    edge pattern's parity where the zone was read and the edge is strong enough, else -1; `angle`
    (float32) the coarse polar angle where lit and modulated enough, else NaN. read: (edge, zone,
    zone_ok, lit); sums: the coarse angle's (S, C); thresholds: (least edge contrast, 2 / steps)."""
    edge, zone, zone_ok, lit = read
    s, c = sums
    least, scale = np.float32(thresholds[0]), np.float32(thresholds[1])
    for y in range(top, bottom):
        for x in range(edge.shape[1]):
            z, e = zone[y, x], edge[y, x]
            a = z if (z % 2 == 1) == (e > 0) else z + 1
            annulus[y, x] = a if zone_ok[y, x] and abs(e) >= least else -1
            modulation = scale * np.float32(math.hypot(s[y, x], c[y, x]))  # as float32 hypot rounds it
            angle[y, x] = atan2(s[y, x], c[y, x]) if lit[y, x] and modulation >= least else np.nan


@njit(**KERNEL)
def edge_crossings(
    edge: np.ndarray, min_step: np.float32
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """rig.patterns.crossings.Crossings.candidates in two passes over the edge image (a count, then
    the crossings), with no image-sized temporaries: the rows and columns of each crossing's pixel
    a (int64), its t (float64) and step (float32), vertical neighbours first, each in row-major
    order, and how many are vertical; float32 arithmetic in numpy's order, so numpy's values."""
    total, vertical = 0, 0
    for axis in range(2):
        for y in range(edge.shape[0] - (axis == 0)):
            for x in range(edge.shape[1] - (axis == 1)):
                total += _crosses(edge, y, x, axis, min_step)
        if axis == 0:
            vertical = total
    rows, cols = np.empty(total, np.int64), np.empty(total, np.int64)
    t, step = np.empty(total), np.empty(total, np.float32)
    n = 0
    for axis in range(2):
        for y in range(edge.shape[0] - (axis == 0)):
            for x in range(edge.shape[1] - (axis == 1)):
                if _crosses(edge, y, x, axis, min_step):
                    d1 = edge[y, x]
                    rows[n], cols[n], step[n] = y, x, d1 - edge[y + (axis == 0), x + (axis == 1)]
                    t[n] = d1 / step[n]
                    n += 1
    return rows, cols, t, step, vertical


@njit(nogil=True, cache=True, inline="always")
def _crosses(edge: np.ndarray, y: int, x: int, axis: int, min_step: np.float32) -> bool:
    """Whether the edge changes sign (0 counting as positive) from (y, x) to its neighbour along
    `axis` by a step of at least `min_step`, and the edge there runs across that axis more than
    along it (np.gradient's slopes, compared only where the first two hold)."""
    d1, d2 = edge[y, x], edge[y + (axis == 0), x + (axis == 1)]
    if (d1 >= 0) == (d2 >= 0) or not abs(d1 - d2) >= min_step:  # `not >=`: a NaN step is none
        return False
    steep = abs(_slope(edge, y, x, 0)) >= abs(_slope(edge, y, x, 1))
    return steep if axis == 0 else not steep


@njit(nogil=True, cache=True, inline="always")
def _slope(edge: np.ndarray, y: int, x: int, axis: int) -> np.float32:
    """np.gradient(edge)[axis] at (y, x): a central difference, one-sided at the image's edge."""
    size, at = edge.shape[axis], y if axis == 0 else x
    dy, dx = (1, 0) if axis == 0 else (0, 1)
    if at == 0:
        return edge[y + dy, x + dx] - edge[y, x]
    if at == size - 1:
        return edge[y, x] - edge[y - dy, x - dx]
    return (edge[y + dy, x + dx] - edge[y - dy, x - dx]) / np.float32(2.0)
