"""The radial decoder's last pass (rig.patterns.radial.RadialStream), compiled by numba as
rig.kernels.dense's loops are: one band of rows [top, bottom) per call, the GIL released.

After the finest angular level's last step the steps are read in one pass (as rig.kernels.phase
reads a period's), the level unwraps the angle the coarser levels gave, and the projector point
(u, v) = centre + R (cos theta, sin theta) is made with the validity tests and counts of
RadialDecoding.correspondence. numba's sin and cos call libm a pixel at a time (76 ms for a
1280x1024 image on one core), so they are polynomials the compiler vectorises.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL, Image
from rig.kernels.phase import atan2, step_sums

_HALF_PI = np.pi / 2
# Taylor coefficients of sin(r) / r and cos(r) in r * r: on |r| <= pi / 4 the first term left out
# is below 1e-11 (sin) and 5e-13 (cos), far below the float32 coordinates made from them.
_SIN = (1.0, -1 / 6, 1 / 120, -1 / 5040, 1 / 362880, -1 / 39916800)
_COS = (1.0, -1 / 2, 1 / 24, -1 / 720, 1 / 40320, -1 / 3628800, 1 / 479001600)
_S0, _S1, _S2, _S3, _S4, _S5 = _SIN
_C0, _C1, _C2, _C3, _C4, _C5, _C6 = _COS


@njit(nogil=True, cache=True, inline="always")
def sincos(angle: float) -> tuple[float, float]:
    """sin and cos of `angle` (float64, |angle| up to a few thousand radians), reduced to the
    nearest quarter turn and chosen by quadrant without branches on the value."""
    turns = np.floor(angle / _HALF_PI + 0.5)
    r = angle - turns * _HALF_PI
    z = r * r
    s = r * (_S0 + z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * _S5)))))
    c = _C0 + z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    quadrant = turns - 4.0 * np.floor(turns * 0.25)  # 0 to 3, kept in floating point: it vectorises
    swap = (quadrant == 1.0) | (quadrant == 3.0)
    sine = (c if swap else s) * (-1.0 if quadrant >= 2.0 else 1.0)
    cosine = (s if swap else c) * (-1.0 if (quadrant == 1.0) | (quadrant == 2.0) else 1.0)
    return sine, cosine


@njit(**KERNEL)
def radial_radius(
    steps: tuple[Image, ...],
    weight_sin: np.ndarray,
    weight_cos: np.ndarray,
    half: Image,
    period: float,
    radius: Image,
    radial_mod: Image,
    top: int,
    bottom: int,
) -> None:
    """The radius (float64 projector pixels) from the radial phase's steps and the half-period
    index `half` of its Gray code, and the radial modulation, as RadialDecoding's constructor
    reads them: near a wrap the index read is one more or one less than the period's."""
    two_pi, quarter, three_quarters = np.float32(2 * np.pi), np.float32(np.pi / 2), np.float32(1.5 * np.pi)
    amplitude = np.float32(2.0 / len(steps))
    width = half.shape[1]
    s, c = np.empty(width, np.float32), np.empty(width, np.float32)
    for y in range(top, bottom):
        step_sums(steps, weight_sin, weight_cos, y, s, c)
        for x in range(width):
            phi, modulation = _wrapped(s[x], c[x], amplitude, two_pi)
            k1, k2 = half[y, x] >> 1, (half[y, x] + 1) >> 1
            k = k2 if phi < quarter else (k2 - 1 if phi > three_quarters else k1)
            radius[y, x] = (np.float64(k) + np.float64(phi / two_pi)) * period
            radial_mod[y, x] = modulation


@njit(**KERNEL)
def angular_level(
    steps: tuple[Image, ...],
    weight_sin: np.ndarray,
    weight_cos: np.ndarray,
    first: bool,
    level: tuple[float, float, float],
    radius: Image,
    theta: Image,
    angular_mod: Image,
    consistent: Image,
    top: int,
    bottom: int,
) -> None:
    """RadialDecoding.add_level from a level's steps: the `first` gives the angle and its
    modulation; each later one refines them (in place) where its fringes are coarse enough."""
    two_pi = np.float32(2 * np.pi)
    amplitude = np.float32(2.0 / len(steps))
    width = radius.shape[1]
    s, c = np.empty(width, np.float32), np.empty(width, np.float32)
    for y in range(top, bottom):
        step_sums(steps, weight_sin, weight_cos, y, s, c)
        for x in range(width):
            wrapped, modulation = _wrapped(s[x], c[x], amplitude, two_pi)
            if first:
                theta[y, x], angular_mod[y, x] = wrapped, modulation
                continue
            refined = _refined(wrapped, modulation, radius[y, x], theta[y, x], angular_mod[y, x], level)
            theta[y, x], angular_mod[y, x] = refined[0], refined[1]
            consistent[y, x] = consistent[y, x] and refined[2]


@njit(nogil=True, cache=True, inline="always")
def _wrapped(s: np.float32, c: np.float32, amplitude: np.float32, two_pi: np.float32) -> tuple[np.float32, np.float32]:
    """The phase in [0, 2 pi) and the modulation of a pixel's summed steps (radial's _phase)."""
    angle = atan2(s, c)
    return (angle + two_pi if angle < 0 else angle), np.sqrt(s * s + c * c) * amplitude


@njit(nogil=True, cache=True, inline="always")
def _refined(
    wrapped: np.float32,
    modulation: np.float32,
    radius: float,
    angle: float,
    angular_mod: np.float32,
    level: tuple[float, float, float],
) -> tuple[float, np.float32, bool]:
    """A later level (its periods per revolution, the least fringe period it is read at, the
    disagreement it allows) at one pixel: the angle unwrapped by it and the least modulation where
    its fringes are usable, and whether it agrees with the angle before (always, where unused)."""
    periods, min_fringe_period, max_disagreement = level
    two_pi = 2 * np.pi
    count = (angle * periods - np.float64(wrapped)) / two_pi
    whole = np.round(count)
    if two_pi * radius / periods < min_fringe_period:
        return angle, angular_mod, True
    return (
        (np.float64(wrapped) + two_pi * whole) / periods,
        min(angular_mod, modulation),
        abs(count - whole) <= max_disagreement,
    )


@njit(nogil=True, cache=True, inline="always")
def _projector_point(
    radius: float, angle: float, center: tuple[float, float], extent: tuple[int, int]
) -> tuple[np.float32, np.float32, bool]:
    """centre + R (cos theta, sin theta) in float32, and whether it lies on the projector image."""
    sine, cosine = sincos(angle)
    u, v = np.float32(center[0] + radius * cosine), np.float32(center[1] + radius * sine)
    half = np.float32(0.5)
    return u, v, (-half < u) & (u < np.float32(extent[0]) - half) & (-half < v) & (v < np.float32(extent[1]) - half)


@njit(**KERNEL)
def radial_finish(
    steps: tuple[Image, ...],
    weight_sin: np.ndarray,
    weight_cos: np.ndarray,
    level: tuple[float, float, float],
    min_modulation: np.float32,
    center: tuple[float, float],
    extent: tuple[int, int],
    lit: Image,
    gray_strong: Image,
    consistent: Image,
    radial_mod: Image,
    angular_mod: Image,
    radius: Image,
    theta: Image,
    u: Image,
    v: Image,
    valid: Image,
    quality: Image,
    radius_out: Image,
    theta_out: Image,
    top: int,
    bottom: int,
) -> tuple[int, int, int, int, int]:
    """The finest `level` (as angular_level's) read from its steps, as RadialDecoding.add_level
    reads it, then RadialDecoding.correspondence: u, v (NaN where not valid), the validity, the
    quality and the float32 radius and angle in [0, 2 pi). Returns the counts of lit pixels, of lit
    pixels with too low a radial or angular modulation, with inconsistent levels, and decoded."""
    two_pi, nan = 2 * np.pi, np.float32(np.nan)
    amplitude = np.float32(2.0 / len(steps))
    lit_count = low_radial = low_angular = inconsistent = decoded = 0
    width = lit.shape[1]
    s, c = np.empty(width, np.float32), np.empty(width, np.float32)
    for y in range(top, bottom):
        step_sums(steps, weight_sin, weight_cos, y, s, c)
        for x in range(width):
            wrapped, modulation = _wrapped(s[x], c[x], amplitude, np.float32(two_pi))
            r = radius[y, x]
            angle, a_mod, agrees = _refined(wrapped, modulation, r, theta[y, x], angular_mod[y, x], level)
            fits = consistent[y, x] & agrees
            r_mod, is_lit = radial_mod[y, x], lit[y, x]
            ok = is_lit & (r_mod >= min_modulation) & (a_mod >= min_modulation)
            ok = ok & gray_strong[y, x] & (r > 0) & fits
            pu, pv, inside = _projector_point(r, angle, center, extent)
            ok = ok & inside
            u[y, x] = pu if ok else nan
            v[y, x] = pv if ok else nan
            valid[y, x] = ok
            quality[y, x] = min(r_mod, a_mod)
            radius_out[y, x] = np.float32(r)
            theta_out[y, x] = np.float32(angle - np.floor(angle / two_pi) * two_pi)
            lit_count += is_lit
            low_radial += is_lit & (r_mod < min_modulation)
            low_angular += is_lit & (a_mod < min_modulation)
            inconsistent += is_lit & (not fits)
            decoded += ok
    return lit_count, low_radial, low_angular, inconsistent, decoded
