"""Per-pixel loops compiled by numba, for the paths that must keep pace with the projector.

Each loop does in one pass over a band of rows what numpy or OpenCV do in several passes over the
whole image: decoding a frame as it arrives (rig.patterns.stream) and the organised cloud after the
last frame (rig.pipeline.organised). Measured on the default bench (1280x1024, 2 cores): the
organised cloud in 8 ms against 27 to 38 ms as numpy passes on row strips (scratch, 9 runs each).

The loops release the GIL and take a band of rows [top, bottom), so rig.workers runs them on its
pool, one band per thread (numba's own parallel loops would start a second pool beside it, and its
default threading layer aborts the process when two threads launch kernels at once). They are
compiled on first use and cached beside this file (__pycache__). Arithmetic stays in the arrays'
float32, with the operations of the batch code they replace, so that results agree with it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_KERNEL = {"nogil": True, "cache": True}
Image = np.ndarray  # (H, W), or (3, H, W) for points, directions and normals


@njit(**_KERNEL)
def gray_pair(
    pattern: Image, inverse: Image, shift: int, value: Image, weakest: Image, second: Image, top: int, bottom: int
) -> None:
    """One Gray bit of rows [top, bottom): the binary value's bit `shift` is the Gray bit XOR the
    binary bit above it (read before); `weakest` and `second` keep the two smallest
    |pattern - inverse|. Arithmetic in uint16 (an int64 shift stops the loop vectorising: 28 ms
    against 0.35 for a 1280x1024 pair on one core)."""
    one, zero, at = np.uint16(1), np.uint16(0), np.uint16(shift)
    for y in range(top, bottom):
        for x in range(pattern.shape[1]):
            a, b = pattern[y, x], inverse[y, x]
            v = value[y, x]
            bit = ((v >> (at + one)) & one) ^ (one if a > b else zero)
            value[y, x] = v | (bit << at)
            strength = a - b if a > b else b - a
            w = weakest[y, x]
            if strength < w:
                second[y, x] = w
                weakest[y, x] = strength
            elif strength < second[y, x]:
                second[y, x] = strength


@njit(**_KERNEL)
def contrast_and_lit(
    white: Image,
    black: Image,
    scale: np.float32,
    threshold: float,
    contrast: Image,
    lit: Image,
    valid: Image,
    top: int,
    bottom: int,
) -> int:
    """(white - black) in fractions of full scale (each frame scaled first, as the batch decoder
    does) and whether it reaches `threshold` (`lit`, and `valid` the same to start from). Returns
    how many pixels are lit."""
    count = 0
    for y in range(top, bottom):
        for x in range(white.shape[1]):
            value = np.float32(white[y, x]) * scale - np.float32(black[y, x]) * scale
            contrast[y, x] = value
            on = value >= threshold
            lit[y, x] = on
            valid[y, x] = on
            count += on
    return count


@njit(**_KERNEL)
def gray_accept(
    value: Image,
    second: Image,
    min_strength: int,
    extent: int,
    lit: Image,
    valid: Image,
    coordinate: Image,
    top: int,
    bottom: int,
) -> int:
    """A Gray-coded axis read whole, in one pass: a pixel stays valid where its bits are strong
    enough (the second-weakest |pattern - inverse| reaches `min_strength` counts) and its code is
    within `extent`; its coordinate, NaN where not valid. Returns how many lit pixels it drops."""
    nan, dropped = np.float32(np.nan), 0
    for y in range(top, bottom):
        for x in range(value.shape[1]):
            v = value[y, x]
            ok = second[y, x] >= min_strength and v < extent
            if lit[y, x] and not ok:
                dropped += 1
            keep = valid[y, x] and ok
            valid[y, x] = keep
            coordinate[y, x] = np.float32(v) if keep else nan
    return dropped


@njit(**_KERNEL)
def phase_step(
    image: Image, weight_sin: np.float32, weight_cos: np.float32, s: Image, c: Image, top: int, bottom: int
) -> None:
    """Add one phase step into the running sums: s += image * weight_sin, c += image * weight_cos."""
    for y in range(top, bottom):
        for x in range(image.shape[1]):
            value = np.float32(image[y, x])
            s[y, x] += value * weight_sin
            c[y, x] += value * weight_cos


@njit(**_KERNEL)
def phase_wrap(
    s: Image,
    c: Image,
    phi: Image,
    amplitude: np.float32,
    period: np.float32,
    modulation: Image,
    near: Image,
    fraction: Image,
    top: int,
    bottom: int,
) -> None:
    """After the last step: the modulation (amplitude * |(s, c)|), the phase phi = atan2(s, c) (given
    for rows [top, bottom) from row `top`: numpy's vectorised atan2 is several times numba's) in
    [0, 2 pi) as a fraction of a period, minus one period past 3 pi / 2 (there the period index read
    is one more), and whether phi is near a wrap (below pi / 2 or past 3 pi / 2)."""
    two_pi, quarter, three_quarters = np.float32(2 * np.pi), np.float32(np.pi / 2), np.float32(1.5 * np.pi)
    per_radian = period / two_pi
    for y in range(top, bottom):
        for x in range(s.shape[1]):
            sy, cx = s[y, x], c[y, x]
            modulation[y, x] = np.sqrt(sy * sy + cx * cx) * amplitude
            angle = phi[y - top, x]
            if angle < 0:
                angle += two_pi
            past = angle > three_quarters
            near[y, x] = 1 if (angle < quarter or past) else 0
            if past:
                angle -= two_pi
            fraction[y, x] = angle * per_radian


@njit(**_KERNEL)
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
    x_out: Image,
    ok: Image,
    weak: Image,
    top: int,
    bottom: int,
) -> None:
    """The projector coordinate from the half-period index and the wrapped phase, and whether it is
    kept: modulation and Gray bits strong enough, within [-0.5, extent - 0.5)."""
    for y in range(top, bottom):
        for x in range(half.shape[1]):
            k = (np.int32(half[y, x]) + np.int32(near[y, x])) >> 1
            coordinate = fraction[y, x] + np.float32(k) * period
            x_out[y, x] = coordinate
            low = modulation[y, x] < min_modulation
            weak[y, x] = low
            inside = coordinate > np.float32(-0.5) and coordinate < extent - np.float32(0.5)
            ok[y, x] = (not low) and second[y, x] >= min_strength and inside


@njit(**_KERNEL)
def plane_triangulate(
    coded: Image,
    valid: Image,
    a: Image,
    b: Image,
    c: Image,
    d: Image,
    scale: np.float32,
    shift: np.float32,
    along_axis: Image,
    directions: Image,
    xyz: Image,
    depth: Image,
    decoded: Image,
    top: int,
    bottom: int,
) -> None:
    """Camera rays against the planes of coded projector columns (or rows): the ray parameter
    s = (a + b x) / (c + d x); the point s * direction (relative to the camera centre), its depth
    along the camera axis, NaN where not decoded or the ray runs along the plane or behind."""
    nan, tiny, one = np.float32(np.nan), np.float32(1e-3), np.float32(1)
    for y in range(top, bottom):
        for x in range(coded.shape[1]):
            u = coded[y, x]
            ok = valid[y, x]
            s = nan
            if ok:
                denominator = c[y, x] + d[y, x] * u
                normalised = u * scale + shift
                s = (a[y, x] + b[y, x] * u) / denominator
                ok = abs(denominator) >= tiny * np.sqrt(one + normalised * normalised) and s > 0
                if not ok:
                    s = nan
            decoded[y, x] = ok
            depth[y, x] = s * along_axis[y, x]
            for axis in range(3):
                xyz[axis, y, x] = s * directions[axis, y, x]


@njit(**_KERNEL)
def _support_at_border(depth: Image, y: int, x: int, max_jump: np.float32) -> int:
    """How many of pixel (y, x)'s neighbours on the image lie within `max_jump` of its depth."""
    height, width = depth.shape
    support = 0
    for yy in range(max(y - 1, 0), min(y + 2, height)):
        for xx in range(max(x - 1, 0), min(x + 2, width)):
            if (yy != y or xx != x) and abs(depth[y, x] - depth[yy, xx]) <= max_jump:
                support += 1
    return support


@njit(**_KERNEL)
def _support_row(depth: Image, y: int, max_jump: np.float32, support: np.ndarray) -> None:
    """How many of the 8 neighbours of each pixel of row y lie within `max_jump` of its depth."""
    height, width = depth.shape
    if y == 0 or y == height - 1:
        for x in range(width):
            support[x] = _support_at_border(depth, y, x, max_jump)
        return
    above, here, below = depth[y - 1], depth[y], depth[y + 1]
    support[0] = _support_at_border(depth, y, 0, max_jump)
    support[width - 1] = _support_at_border(depth, y, width - 1, max_jump)
    for x in range(1, width - 1):  # no bounds to check: a loop the compiler vectorises
        z = here[x]
        count = np.int32(abs(z - above[x - 1]) <= max_jump) + np.int32(abs(z - above[x]) <= max_jump)
        count += np.int32(abs(z - above[x + 1]) <= max_jump) + np.int32(abs(z - here[x - 1]) <= max_jump)
        count += np.int32(abs(z - here[x + 1]) <= max_jump) + np.int32(abs(z - below[x - 1]) <= max_jump)
        count += np.int32(abs(z - below[x]) <= max_jump) + np.int32(abs(z - below[x + 1]) <= max_jump)
        support[x] = count


@njit(**_KERNEL)
def reject_isolated(
    depth: Image, decoded: Image, max_jump: np.float32, min_support: int, keep: Image, xyz: Image, top: int, bottom: int
) -> int:
    """Keep a decoded point with at least `min_support` of its 8 neighbours within `max_jump` in
    depth (rig.pipeline.dense.reject_isolated); a point dropped becomes NaN. Returns the count dropped."""
    nan, dropped = np.float32(np.nan), 0
    support = np.empty(depth.shape[1], np.int32)
    for y in range(top, bottom):
        _support_row(depth, y, max_jump, support)
        for x in range(depth.shape[1]):
            kept = decoded[y, x] and support[x] >= min_support
            keep[y, x] = kept
            if decoded[y, x] and not kept:
                dropped += 1
                for axis in range(3):
                    xyz[axis, y, x] = nan
    return dropped


@njit(**_KERNEL)
def grid_normals(xyz: Image, rays: Image, step: int, out: Image, top: int, bottom: int) -> None:
    """rig.pipeline.dense.grid_normals: the cross product of the differences `step` pixels across
    and down, unit, turned toward the camera (against its `rays`); -ray where a neighbour is missing
    or off the image."""
    height, width = xyz.shape[1], xyz.shape[2]
    for y in range(top, bottom):
        for x in range(width):
            if y < step or y >= height - step or x < step or x >= width - step:
                for axis in range(3):
                    out[axis, y, x] = -rays[axis, y, x]
                continue
            ux = xyz[0, y, x + step] - xyz[0, y, x - step]
            uy = xyz[1, y, x + step] - xyz[1, y, x - step]
            uz = xyz[2, y, x + step] - xyz[2, y, x - step]
            vx = xyz[0, y + step, x] - xyz[0, y - step, x]
            vy = xyz[1, y + step, x] - xyz[1, y - step, x]
            vz = xyz[2, y + step, x] - xyz[2, y - step, x]
            nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
            norm = np.sqrt(nx * nx + ny * ny + nz * nz)
            if not np.isfinite(norm):
                for axis in range(3):
                    out[axis, y, x] = -rays[axis, y, x]
                continue
            scale = np.float32(1) / norm
            if nx * rays[0, y, x] + ny * rays[1, y, x] + nz * rays[2, y, x] > 0:
                scale = -scale
            out[0, y, x], out[1, y, x], out[2, y, x] = nx * scale, ny * scale, nz * scale
