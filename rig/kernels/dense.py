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

from rig.kernels import KERNEL, Image


@njit(**KERNEL)
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


@njit(**KERNEL)
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
    does) and whether it reaches `threshold` (`lit`, and `valid` the same to start from); the
    contrast is written only where `contrast` is an image (an empty one: the codec does not use it).
    Returns how many pixels are lit."""
    count, keep = 0, contrast.size > 0
    for y in range(top, bottom):
        for x in range(white.shape[1]):
            value = np.float32(white[y, x]) * scale - np.float32(black[y, x]) * scale
            if keep:
                contrast[y, x] = value
            on = value >= threshold
            lit[y, x] = on
            valid[y, x] = on
            count += on
    return count


@njit(**KERNEL)
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
            ok = (second[y, x] >= min_strength) & (v < extent)
            dropped += np.int32(lit[y, x] & (not ok))
            keep = valid[y, x] & ok
            valid[y, x] = keep
            coordinate[y, x] = np.float32(v) if keep else nan
    return dropped


@njit(**KERNEL, error_model="numpy")
def plane_triangulate(
    coded: Image,
    valid: Image,
    constants: tuple[np.float32, np.float32],
    c: Image,
    d: Image,
    scale: np.float32,
    shift: np.float32,
    along_axis: Image,
    ray: Image,
    depth: Image,
    decoded: Image,
    top: int,
    bottom: int,
) -> None:
    """Camera rays against the planes of coded projector columns (or rows): the ray parameter
    s = (a + b x) / (c + d x) (the point is s * direction, relative to the camera centre; a and b,
    `constants`, the same at every pixel) and its depth along the camera axis, NaN where not decoded
    or the ray runs along the plane or behind. Every pixel takes the same steps, whatever it reads
    (numpy's float division: a ray in the plane gives inf, not an exception), so the loop runs in
    vector lanes: 2.5 times as fast as with a branch per pixel on a 5 MP image."""
    a, b = constants
    for y in range(top, bottom):
        for x in range(coded.shape[1]):
            s, ok = plane_point(coded[y, x], valid[y, x], c[y, x], d[y, x], (a, b, scale, shift))
            decoded[y, x] = ok
            depth[y, x] = s * along_axis[y, x]
            ray[y, x] = s


@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def plane_point(
    u: np.float32, valid: bool, c: np.float32, d: np.float32, terms: tuple[np.float32, ...]
) -> tuple[np.float32, bool]:
    """One pixel's ray parameter s = (a + b u) / (c + d u) against the plane of coded coordinate u
    (`terms`: a, b, scale and shift, u normalised = scale u + shift) and whether it is a point: NaN
    and False where not valid, the ray runs along the plane or meets it behind."""
    nan, tiny, one, zero = np.float32(np.nan), np.float32(1e-3), np.float32(1), np.float32(0)
    a, b, scale, shift = terms
    denominator = c + d * u
    normalised = u * scale + shift
    s = (a + b * u) / denominator
    ok = valid and abs(denominator) >= tiny * np.sqrt(one + normalised * normalised) and s > zero
    return (s if ok else nan), ok


@njit(**KERNEL, error_model="numpy")
def ray_ray_triangulate(
    u: Image,
    v: Image,
    valid: Image,
    directions: Image,
    to_ray: np.ndarray,
    offset: np.ndarray,
    along_axis: Image,
    ray: Image,
    depth: Image,
    decoded: Image,
    top: int,
    bottom: int,
) -> None:
    """Both projector coordinates decoded: the point of each unit camera ray closest to the
    projector ray to_ray @ (u, v, 1) (PairTriangulator._ray_ray_fast, in float64 per pixel), as
    plane_triangulate writes it; NaN where the rays are parallel or meet behind either device.
    `offset`: the camera centre minus the projector centre. Every pixel takes the same steps, as in
    plane_triangulate (a pixel not decoded, or parallel rays, divides into NaN or inf and is
    dropped after), so the loop runs in vector lanes: a third of the time of a branch per pixel."""
    nan = np.float32(np.nan)
    t00, t01, t02 = to_ray[0, 0], to_ray[0, 1], to_ray[0, 2]
    t10, t11, t12 = to_ray[1, 0], to_ray[1, 1], to_ray[1, 2]
    t20, t21, t22 = to_ray[2, 0], to_ray[2, 1], to_ray[2, 2]
    o0, o1, o2 = offset[0], offset[1], offset[2]
    for y in range(top, bottom):
        for x in range(u.shape[1]):
            cu, cv = np.float64(u[y, x]), np.float64(v[y, x])
            p0 = t00 * cu + t01 * cv + t02
            p1 = t10 * cu + t11 * cv + t12
            p2 = t20 * cu + t21 * cv + t22
            c0 = np.float64(directions[0, y, x])
            c1 = np.float64(directions[1, y, x])
            c2 = np.float64(directions[2, y, x])
            b = c0 * p0 + c1 * p1 + c2 * p2
            c = p0 * p0 + p1 * p1 + p2 * p2
            e = p0 * o0 + p1 * o1 + p2 * o2
            f = c0 * o0 + c1 * o1 + c2 * o2
            denominator = c - b * b
            along_camera = (b * e - c * f) / denominator
            ok = valid[y, x] and denominator >= 1e-6 * c and along_camera > 0 and (e - b * f) / denominator > 0
            s = np.float32(along_camera) if ok else nan
            decoded[y, x] = ok
            depth[y, x] = s * along_axis[y, x]
            ray[y, x] = s


@njit(**KERNEL)
def blank_unkept(depth: Image, keep: Image, top: int, bottom: int) -> int:
    """NaN in `depth` where `keep` is clear (a depth image of the points kept); the count kept."""
    nan, kept = np.float32(np.nan), 0
    for y in range(top, bottom):
        for x in range(depth.shape[1]):
            if keep[y, x]:
                kept += 1
            else:
                depth[y, x] = nan
    return kept


@njit(nogil=True, cache=True)
def support_of_rows(
    rows: tuple[np.ndarray, np.ndarray, np.ndarray], y: int, height: int, max_jump: np.float32, support: np.ndarray
) -> None:
    """How many of the 8 neighbours on the image of each pixel of row y (of `height`) lie within
    `max_jump` of its depth, from that row's depths and those of the rows above and below it (any
    row where y has none)."""
    above, here, below = rows
    width = len(here)
    if y == 0 or y == height - 1 or width < 2:
        for x in range(width):
            support[x] = _support_at_edge(rows, y, x, height, max_jump)
        return
    support[0] = _support_at_edge(rows, y, 0, height, max_jump)
    support[width - 1] = _support_at_edge(rows, y, width - 1, height, max_jump)
    for x in range(1, width - 1):  # no bounds to check: a loop the compiler vectorises
        z = here[x]
        count = np.int32(abs(z - above[x - 1]) <= max_jump) + np.int32(abs(z - above[x]) <= max_jump)
        count += np.int32(abs(z - above[x + 1]) <= max_jump) + np.int32(abs(z - here[x - 1]) <= max_jump)
        count += np.int32(abs(z - here[x + 1]) <= max_jump) + np.int32(abs(z - below[x - 1]) <= max_jump)
        count += np.int32(abs(z - below[x]) <= max_jump) + np.int32(abs(z - below[x + 1]) <= max_jump)
        support[x] = count


@njit(nogil=True, cache=True)
def _support_at_edge(
    rows: tuple[np.ndarray, np.ndarray, np.ndarray], y: int, x: int, height: int, max_jump: np.float32
) -> int:
    """support_of_rows at one pixel, counting only the neighbours on the image."""
    width, support, z = len(rows[1]), 0, rows[1][x]
    for dy in range(-1 if y > 0 else 0, 2 if y < height - 1 else 1):
        row = rows[dy + 1]
        for xx in range(max(x - 1, 0), min(x + 2, width)):
            if (dy != 0 or xx != x) and abs(z - row[xx]) <= max_jump:
                support += 1
    return support


@njit(**KERNEL)
def reject_isolated(
    depth: Image, decoded: Image, max_jump: np.float32, min_support: int, keep: Image, ray: Image, top: int, bottom: int
) -> int:
    """Keep a decoded point with at least `min_support` of its 8 neighbours within `max_jump` in
    depth (rig.pipeline.dense.reject_isolated); a point dropped gets a NaN `ray` parameter.
    Returns the count dropped."""
    nan, dropped = np.float32(np.nan), 0
    support = np.empty(depth.shape[1], np.int32)
    height = depth.shape[0]
    for y in range(top, bottom):
        support_of_rows((depth[max(y - 1, 0)], depth[y], depth[min(y + 1, height - 1)]), y, height, max_jump, support)
        for x in range(depth.shape[1]):  # no branch per pixel: the loop runs in vector lanes
            was = decoded[y, x]
            kept = was and support[x] >= min_support
            keep[y, x] = kept
            lost = was and not kept
            dropped += lost
            ray[y, x] = nan if lost else ray[y, x]
    return dropped


@njit(nogil=True, cache=True, inline="always")
def _normal(ray: Image, directions: Image, step: int, y: int, x: int) -> tuple[float, float, float]:
    """rig.pipeline.dense.grid_normals at one pixel of the points ray * directions: the cross
    product of the differences `step` pixels across and down, unit, turned toward the camera;
    -direction where a neighbour is missing or off the image. Each point is made where it is
    needed, the same float32 product an image of them would hold."""
    height, width = ray.shape
    if y < step or y >= height - step or x < step or x >= width - step:
        return -directions[0, y, x], -directions[1, y, x], -directions[2, y, x]
    right, left, below, above = ray[y, x + step], ray[y, x - step], ray[y + step, x], ray[y - step, x]
    ux = right * directions[0, y, x + step] - left * directions[0, y, x - step]
    uy = right * directions[1, y, x + step] - left * directions[1, y, x - step]
    uz = right * directions[2, y, x + step] - left * directions[2, y, x - step]
    vx = below * directions[0, y + step, x] - above * directions[0, y - step, x]
    vy = below * directions[1, y + step, x] - above * directions[1, y - step, x]
    vz = below * directions[2, y + step, x] - above * directions[2, y - step, x]
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    if not np.isfinite(norm):
        return -directions[0, y, x], -directions[1, y, x], -directions[2, y, x]
    scale = np.float32(1) / norm
    if nx * directions[0, y, x] + ny * directions[1, y, x] + nz * directions[2, y, x] > 0:
        scale = -scale
    return nx * scale, ny * scale, nz * scale


@njit(**KERNEL)
def kept_normals(
    ray: Image, directions: Image, step: int, keep: Image, first: np.ndarray, out: np.ndarray, top: int, bottom: int
) -> None:
    """The normals (rig.pipeline.dense.grid_normals) of the `keep` pixels only, in row-major order:
    row y's kept pixels fill out[first[y]:first[y + 1]] of `out` (N, 3), the PointSet's own
    normals, so no (3, H, W) image of them is made and gathered."""
    for y in range(top, bottom):
        k = first[y]
        for x in range(ray.shape[1]):
            if keep[y, x]:
                out[k, 0], out[k, 1], out[k, 2] = _normal(ray, directions, step, y, x)
                k += 1


@njit(**KERNEL)
def kept_points(
    ray: Image,
    directions: Image,
    keep: Image,
    first: np.ndarray,
    origin: np.ndarray,
    colours: np.ndarray,
    quality: Image,
    out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    top: int,
    bottom: int,
) -> None:
    """The world points (float32, ray * direction + origin, the sum in float64), flat pixel
    indices, colours (`colours` (H, W, 3) at the pixel) and quality (float32) of the `keep` pixels,
    in row-major order as kept_normals lays them out: `out` = (points, pixels, colours, quality)."""
    points, pixel, colour, grade = out
    width = ray.shape[1]
    for y in range(top, bottom):
        k = first[y]
        for x in range(width):
            if keep[y, x]:
                s = ray[y, x]
                for axis in range(3):
                    points[k, axis] = np.float32(np.float64(s * directions[axis, y, x]) + origin[axis])
                    colour[k, axis] = colours[y, x, axis]
                pixel[k] = y * width + x
                grade[k] = np.float32(quality[y, x])
                k += 1


@njit(**KERNEL)
def ray_angles(
    points: np.ndarray, camera: np.ndarray, projector: np.ndarray, out: np.ndarray, start: int, stop: int
) -> None:
    """The angle (degrees, float32) at each of points[start:stop] between the rays from the two
    device centres (rig.pipeline.merge.triangulation_angles for pinhole devices)."""
    to_degrees = np.float32(180 / np.pi)
    c0, c1, c2 = np.float32(camera[0]), np.float32(camera[1]), np.float32(camera[2])
    p0, p1, p2 = np.float32(projector[0]), np.float32(projector[1]), np.float32(projector[2])
    for k in range(start, stop):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        ax, ay, az = x - c0, y - c1, z - c2
        bx, by, bz = x - p0, y - p1, z - p2
        cos = (ax * bx + ay * by + az * bz) / np.sqrt((ax * ax + ay * ay + az * az) * (bx * bx + by * by + bz * bz))
        out[k] = np.arccos(min(max(cos, np.float32(-1)), np.float32(1))) * to_degrees
