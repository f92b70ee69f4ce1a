"""The phase decoder's per-pixel loops (rig.patterns.phase.PhaseStream), compiled by numba as
rig.kernels.dense's are: one band of rows [top, bottom) per call, the GIL released.

A period's steps are read in one pass after its last step arrives (each frame read once, its sums
kept in registers for a row) rather than added into two float32 images step by step, which read and
wrote 8 bytes a pixel per step; holding the steps costs what the two sums did (one byte a pixel
each for 8 steps). The phase's atan2 is a polynomial the compiler vectorises: numba's atan2 calls
libm one pixel at a time, several times slower than numpy's.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL, Image

# atan(t) / t as a polynomial in t * t on [0, 1]: least-squares coefficients, reweighted toward the
# largest error (fitted in float64, evaluated in float32). Largest error against atan: 9.5e-8 rad,
# 1.5 units in the last place at pi / 4 (tests/test_stream_decode.py checks it).
_ATAN = (
    0.9999998807907104,
    -0.33332598209381104,
    0.19985906779766083,
    -0.14161229133605957,
    0.10498946160078049,
    -0.07234856486320496,
    0.03978121280670166,
    -0.014401348307728767,
    0.002456721616908908,
)
_A0, _A1, _A2, _A3, _A4, _A5, _A6, _A7, _A8 = (np.float32(a) for a in _ATAN)


@njit(**KERNEL)
def atan2(y: np.float32, x: np.float32) -> np.float32:
    """atan2(y, x) in float32, in (-pi, pi] (0 at the origin), without branches on the value so
    that a loop over pixels vectorises."""
    ax, ay = abs(x), abs(y)
    big, small = max(ax, ay), min(ax, ay)
    t = small / big if big > 0 else np.float32(0)
    z = t * t
    p = _A8 * z + _A7
    p = p * z + _A6
    p = p * z + _A5
    p = p * z + _A4
    p = p * z + _A3
    p = p * z + _A2
    p = p * z + _A1
    p = p * z + _A0
    angle = p * t
    angle = np.float32(np.pi / 2) - angle if ay > ax else angle
    angle = np.float32(np.pi) - angle if x < 0 else angle
    return -angle if y < 0 else angle


@njit(**KERNEL)
def step_sums(
    steps: tuple[Image, ...], weight_sin: np.ndarray, weight_cos: np.ndarray, y: int, s: np.ndarray, c: np.ndarray
) -> None:
    """Row `y`'s sums of the steps times their sine and cosine weights, in step order (as the batch
    decoder adds them), into `s` and `c`."""
    s[:] = 0
    c[:] = 0
    for n in range(len(steps)):
        row, ws, wc = steps[n][y], weight_sin[n], weight_cos[n]
        for x in range(s.shape[0]):
            value = np.float32(row[x])
            s[x] += value * ws
            c[x] += value * wc


@njit(**KERNEL)
def phase_wrap(
    steps: tuple[Image, ...],
    weight_sin: np.ndarray,
    weight_cos: np.ndarray,
    amplitude: np.float32,
    period: np.float32,
    modulation: Image,
    near: Image,
    fraction: Image,
    top: int,
    bottom: int,
) -> None:
    """A period's steps read whole: s = sum of step n * weight_sin[n], c likewise (in step order,
    as the batch decoder adds them); the modulation (amplitude * |(s, c)|); the phase atan2(s, c)
    in [0, 2 pi) as a fraction of a period, minus one period past 3 pi / 2 (there the period index
    read is one more); and whether it is near a wrap (below pi / 2 or past 3 pi / 2)."""
    two_pi, quarter, three_quarters = np.float32(2 * np.pi), np.float32(np.pi / 2), np.float32(1.5 * np.pi)
    per_radian = period / two_pi
    width = modulation.shape[1]
    s, c = np.empty(width, np.float32), np.empty(width, np.float32)
    for y in range(top, bottom):
        step_sums(steps, weight_sin, weight_cos, y, s, c)
        for x in range(width):
            sy, cx = s[x], c[x]
            modulation[y, x] = np.sqrt(sy * sy + cx * cx) * amplitude
            angle = atan2(sy, cx)
            angle = angle + two_pi if angle < 0 else angle
            past = angle > three_quarters
            near[y, x] = 1 if (angle < quarter or past) else 0
            angle = angle - two_pi if past else angle
            fraction[y, x] = angle * per_radian


@njit(**KERNEL)
def phase_unwrap(
    half: Image,
    near: Image,
    fraction: Image,
    modulation: Image,
    second: Image,
    period: np.float32,
    min_modulation: float,
    min_strength: int,
    extent: int,
    lit: Image,
    valid: Image,
    quality: Image,
    lower_quality: bool,
    top: int,
    bottom: int,
) -> int:
    """The projector coordinate from the half-period index and the wrapped phase, in one pass: a
    pixel stays valid where the modulation and the Gray bits are strong enough and the coordinate
    lies within [-0.5, extent - 0.5); the coordinate is written over `fraction` (NaN where not
    valid); with `lower_quality`, `quality` is lowered to the modulation. Returns how many lit
    pixels have too low a modulation.

    No array may be another (an output that is also an input stops the loop vectorising: 2.4 ms
    against 1.0 for 1280x1024 on 2 cores), hence one array for the fraction and the coordinate."""
    nan, low_count = np.float32(np.nan), 0
    for y in range(top, bottom):
        for x in range(half.shape[1]):
            k = (np.int32(half[y, x]) + np.int32(near[y, x])) >> 1
            coordinate = fraction[y, x] + np.float32(k) * period
            m = modulation[y, x]
            low = m < min_modulation
            low_count += np.int32(lit[y, x] & low)
            inside = (coordinate > np.float32(-0.5)) & (coordinate < extent - np.float32(0.5))
            ok = valid[y, x] & (not low) & (second[y, x] >= min_strength) & inside
            valid[y, x] = ok
            fraction[y, x] = coordinate if ok else nan
            if lower_quality:
                quality[y, x] = min(quality[y, x], m)
    return low_count


# what cued_unwrap finds at a pixel (rig.patterns.cued_phase numbers them alike: a test holds them together)
UNLIT, DECODED, CUE_OFF, OUTSIDE, LOW_MODULATION = 0, 1, 2, 3, 4


@njit(**KERNEL)
def cued_unwrap(
    steps: tuple[Image, ...],
    weight_sin: np.ndarray,
    weight_cos: np.ndarray,
    cue_period: np.float32,
    period: np.float32,
    extent: int,
    black_threshold: np.float32,
    min_modulation: np.float32,
    cue_margin: np.float32,
    modulation: Image,
    coordinate: Image,
    status: Image,
    top: int,
    bottom: int,
) -> None:
    """The cue's steps read whole (as phase_wrap reads a period's) and the fine coordinate in
    `coordinate` (mod `period`, phase_wrap's fraction) unwrapped by it, in one pass
    (rig.patterns.cued_phase): written over it, NaN where not DECODED. `status`: UNLIT where twice
    the fringes' modulation is below `black_threshold`, LOW_MODULATION where either modulation is
    below `min_modulation`, CUE_OFF where the cue lies further than `cue_margin` periods from the
    result, OUTSIDE where the result is beyond [-0.5, extent - 0.5)."""
    two_pi, nan = np.float32(2 * np.pi), np.float32(np.nan)
    per_radian, amplitude = cue_period / two_pi, np.float32(2.0 / len(steps))
    beyond = np.float32(extent) + period / np.float32(2)  # a cue past here is noise about 0
    # the codes as bytes, as status holds them: int64 codes took a quarter longer (wider vector lanes)
    unlit, decoded, cue_off = np.uint8(UNLIT), np.uint8(DECODED), np.uint8(CUE_OFF)
    outside, low_modulation = np.uint8(OUTSIDE), np.uint8(LOW_MODULATION)
    lowest, highest = np.float32(-0.5), np.float32(extent) - np.float32(0.5)
    width = coordinate.shape[1]
    s, c = np.empty(width, np.float32), np.empty(width, np.float32)
    for y in range(top, bottom):
        step_sums(steps, weight_sin, weight_cos, y, s, c)
        for x in range(width):
            sy, cx = s[x], c[x]
            angle = atan2(sy, cx)
            angle = angle + two_pi if angle < 0 else angle
            cue = angle * per_radian
            cue = cue - cue_period if cue > beyond else cue
            fine = coordinate[y, x]
            result = np.float32(np.floor((cue - fine) / period + np.float32(0.5))) * period + fine
            found = decoded if lowest < result < highest else outside
            found = found if abs(result - cue) <= cue_margin * period else cue_off
            fringe = modulation[y, x]
            found = found if min(fringe, np.sqrt(sy * sy + cx * cx) * amplitude) >= min_modulation else low_modulation
            found = found if fringe + fringe >= black_threshold else unlit
            status[y, x] = found
            coordinate[y, x] = result if found == decoded else nan


@njit(**KERNEL)
def twice_mean(frames: tuple[Image, ...], full_scale: np.float32, out: Image, top: int, bottom: int) -> None:
    """Twice the frames' mean (float32, the sum in frame order as rig.patterns.cued_phase.texture
    adds them), at most `full_scale`, truncated to `out`'s sample type: a fringe's peak."""
    scale = np.float32(2.0 / len(frames))
    width = out.shape[1]
    total = np.empty(width, np.float32)
    for y in range(top, bottom):
        total[:] = 0
        for n in range(len(frames)):
            row = frames[n][y]
            for x in range(width):
                total[x] += np.float32(row[x])
        for x in range(width):
            out[y, x] = min(total[x] * scale, full_scale)


@njit(**KERNEL)
def account_status(
    status: Image, saturated: Image, any_saturated: bool, coordinate: Image, valid: Image, top: int, bottom: int
) -> np.ndarray:
    """A lit pixel clipped in any frame (`saturated`, read only when `any_saturated`) gets status
    `saturated_code` = LOW_MODULATION + 1; `valid` where DECODED, the coordinate NaN elsewhere.
    Returns the count of each status (0 to LOW_MODULATION + 1), counted in six running sums rather
    than a histogram indexed per pixel, and with no branch per pixel, so that the loop runs in
    vector lanes (two to five times as fast on 12 MP)."""
    saturated_code = np.uint8(LOW_MODULATION + 1)
    nan = np.float32(np.nan)
    unlit = decoded = cue_off = outside = low = clipped = 0
    for y in range(top, bottom):
        for x in range(status.shape[1]):
            code = status[y, x]
            if any_saturated:
                code = saturated_code if saturated[y, x] and code != UNLIT else code
                status[y, x] = code
            unlit += code == UNLIT
            decoded += code == DECODED
            cue_off += code == CUE_OFF
            outside += code == OUTSIDE
            low += code == LOW_MODULATION
            clipped += code == saturated_code
            read = code == DECODED
            valid[y, x] = read
            coordinate[y, x] = coordinate[y, x] if read else nan
    counts = np.zeros(LOW_MODULATION + 2, np.int64)
    counts[UNLIT], counts[DECODED], counts[CUE_OFF] = unlit, decoded, cue_off
    counts[OUTSIDE], counts[LOW_MODULATION], counts[saturated_code] = outside, low, clipped
    return counts
