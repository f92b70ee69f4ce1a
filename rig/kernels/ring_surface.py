"""The ring surface's pixels (rig.pipeline.surface, rig.pipeline.raster), compiled by numba: each
covered camera pixel's point on its triangle's interpolant, and whether the projector lights that
point inside the ring band its pixel read (and the faces whose pixels mostly are not). As numpy
passes over a million pixels they took about 100 ms on two threads for the default bench, 60 as
these loops (one per pixel for each, a span of pixels per call for rig.workers' pool, writing
straight into the camera grid), in the floating-point order of the numpy they replace (but the
band's polar angle: float32's polynomial atan2, within 1e-7 rad)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig.kernels import KERNEL
from rig.kernels.phase import atan2

_GRAZING = 0.1  # a tangent plane met at a cosine below this is left out (the linear point stands)
_ANGLE_MIN_RADIUS_PX = 8.0  # near the rings' centre the polar angle says little: not checked inside this


@njit(**KERNEL)
def face_terms(
    points: np.ndarray,
    xy: np.ndarray,
    tri: np.ndarray,
    corner_normals: np.ndarray,
    origin: np.ndarray,
    faces: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    corners: tuple[np.ndarray, np.ndarray],
) -> None:
    """rig.pipeline.raster.FaceTerms.of: per face `tri` (F, 3), into faces (plane (3, F),
    plane_offset (F,), longest (F,), barycentric (3, 3, F)) and, with `corner_normals` (F, 3, 3;
    empty for the linear interpolant), corners (their normals (3, 3, F), offsets (3, F)); offsets
    from `origin` (zeros where rays have their own)."""
    plane, plane_offset, longest, barycentric = faces
    normals, corner_offset = corners
    quadratic = len(corner_normals) == len(tri)
    c = np.empty((3, 3))
    for f in range(len(tri)):
        for k in range(3):
            for j in range(3):
                c[k, j] = points[tri[f, k], j] - origin[j]
        ux, uy, uz = c[1, 0] - c[0, 0], c[1, 1] - c[0, 1], c[1, 2] - c[0, 2]
        vx, vy, vz = c[2, 0] - c[0, 0], c[2, 1] - c[0, 1], c[2, 2] - c[0, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        norm = max(np.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
        plane[0, f], plane[1, f], plane[2, f] = nx / norm, ny / norm, nz / norm
        plane_offset[f] = plane[0, f] * c[0, 0] + plane[1, f] * c[0, 1] + plane[2, f] * c[0, 2]
        edge = 0.0
        for k in range(3):
            n = (k + 1) % 3
            edge = max(edge, np.sqrt((c[k, 0] - c[n, 0]) ** 2 + (c[k, 1] - c[n, 1]) ** 2 + (c[k, 2] - c[n, 2]) ** 2))
        longest[f] = edge
        _barycentric(xy, tri[f], barycentric, f)
        if quadratic:
            for k in range(3):
                for j in range(3):
                    normals[k, j, f] = corner_normals[f, k, j]
                corner_offset[k, f] = (
                    corner_normals[f, k, 0] * c[k, 0]
                    + corner_normals[f, k, 1] * c[k, 1]
                    + corner_normals[f, k, 2] * c[k, 2]
                )


@njit(nogil=True, cache=True, inline="always")
def _barycentric(xy: np.ndarray, corners: np.ndarray, barycentric: np.ndarray, f: int) -> None:
    """Face f's image barycentric weights as affine functions of the pixel: (b1, b2) = inverse of
    the edges from corner 0 times (pixel - corner 0); corner 0's weight is 1 - b1 - b2."""
    x0, y0 = xy[corners[0], 0], xy[corners[0], 1]
    e1x, e1y = xy[corners[1], 0] - x0, xy[corners[1], 1] - y0
    e2x, e2y = xy[corners[2], 0] - x0, xy[corners[2], 1] - y0
    det = e1x * e2y - e1y * e2x
    det = 1e-12 if abs(det) < 1e-12 else det
    b1x, b1y, b2x, b2y = e2y / det, -e2x / det, -e1y / det, e1x / det
    c1, c2 = -(b1x * x0 + b1y * y0), -(b2x * x0 + b2y * y0)
    barycentric[0, 0, f], barycentric[0, 1, f], barycentric[0, 2, f] = -b1x - b2x, -b1y - b2y, 1.0 - c1 - c2
    barycentric[1, 0, f], barycentric[1, 1, f], barycentric[1, 2, f] = b1x, b1y, c1
    barycentric[2, 0, f], barycentric[2, 1, f], barycentric[2, 2, f] = b2x, b2y, c2


@njit(nogil=True, cache=True, inline="always")
def _along(normal: np.ndarray, offset: np.ndarray, k: int, f: int, ray: tuple[float, ...]) -> tuple[float, float]:
    """Where a ray (origin relative to the terms' origin, or zeros; direction: six numbers) meets
    face f's plane k (normal (K, 3, F), offset (K, F)), and the cosine between them; NaN where
    parallel."""
    ox, oy, oz, dx, dy, dz = ray
    facing = normal[k, 0, f] * dx + normal[k, 1, f] * dy + normal[k, 2, f] * dz
    numerator = offset[k, f] - (normal[k, 0, f] * ox + normal[k, 1, f] * oy + normal[k, 2, f] * oz)
    return (numerator / facing if facing != 0 else np.nan), facing


@njit(**KERNEL)
def points_on_faces(
    faces: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    corners: tuple[np.ndarray, np.ndarray],
    rays: tuple[np.ndarray, np.ndarray],
    pixel: np.ndarray,
    owner: np.ndarray,
    width: int,
    out: tuple[np.ndarray, np.ndarray, np.ndarray],
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.raster.points_on_faces for pixels [start, stop): out (found, rows, finite):
    pixel n's point into row rows[n] of `found` (a flat camera grid, or one row per pixel) and
    whether it is finite into finite[n]. faces (plane (3, F), plane_offset (F,), longest (F,),
    barycentric (3, 3, F)) and corners (their normals (3, 3, F) and offsets (3, F), both empty
    (0, ...) for the linear interpolant) of FaceTerms; rays: origins (1, 3) shared, or (H*W, 3) one
    per pixel, and directions (H*W, 3)."""
    plane, plane_offset, longest, barycentric = faces
    plane, plane_offset = plane.reshape((1, 3, -1)), plane_offset.reshape((1, -1))  # one plane per face
    corner_normals, corner_offset = corners
    origins, directions = rays
    found, rows, finite = out
    shared = len(origins) == 1
    quadratic = corner_normals.shape[0] == 3
    for n in range(start, stop):
        p, f = pixel[n], owner[n]
        start_at = 0 if shared else p
        ray = (0.0, 0.0, 0.0, directions[p, 0], directions[p, 1], directions[p, 2])
        if not shared:
            ray = (origins[p, 0], origins[p, 1], origins[p, 2], ray[3], ray[4], ray[5])
        t_linear, _ = _along(plane, plane_offset, 0, f, ray)
        t = t_linear
        if quadratic:
            row = p // width
            x, y = float(p - row * width), float(row)
            blend, steep = 0.0, False
            for k in range(3):
                t_k, facing = _along(corner_normals, corner_offset, k, f, ray)
                steep = steep or abs(facing) < _GRAZING
                blend += (barycentric[k, 0, f] * x + barycentric[k, 1, f] * y + barycentric[k, 2, f]) * t_k
            reach = 0.25 * longest[f]
            t = t_linear if steep else 0.5 * (t_linear + blend)
            if t < t_linear - reach:
                t = t_linear - reach
            if t > t_linear + reach:
                t = t_linear + reach
        row = rows[n]
        for c in range(3):
            found[row, c] = origins[start_at, c] + t * directions[p, c]
        finite[n] = np.isfinite(found[row, 0]) and np.isfinite(found[row, 1]) and np.isfinite(found[row, 2])


@njit(**KERNEL)
def band_agreement(
    points: tuple[np.ndarray, np.ndarray],
    pixel: np.ndarray,
    projector: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    kind: tuple[bool, bool],
    bands: tuple[np.ndarray, np.ndarray, np.ndarray, float, float],
    margins: tuple[float, float],
    agree: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """rig.pipeline.surface.band_agreement for points [start, stop) into `agree`: points (found,
    rows): point n is found[rows[n]], at flat camera pixel pixel[n]; projector (R, t, K, dist) with
    kind (orthographic, distorted); bands (annulus and angle, flat, radii, centre u, v); margins
    (band_margin_px, band_angle_rad)."""
    found, rows = points
    R, t, K, dist = projector
    orthographic, distorted = kind
    annuli, angles, radii, cu, cv = bands
    margin, max_turn = margins
    rings = len(radii)
    for n in range(start, stop):
        r = rows[n]
        qx, qy, qz = found[r, 0], found[r, 1], found[r, 2]
        x = R[0, 0] * qx + R[0, 1] * qy + R[0, 2] * qz + t[0]
        y = R[1, 0] * qx + R[1, 1] * qy + R[1, 2] * qz + t[1]
        z = R[2, 0] * qx + R[2, 1] * qy + R[2, 2] * qz + t[2]
        if not z > 0:
            agree[n] = False  # behind the projector, or no point
            continue
        if not orthographic:
            x, y = x / z, y / z
        if distorted:
            x, y = _distorted(x, y, dist)
        du = K[0, 0] * x + K[0, 1] * y + K[0, 2] - cu
        dv = K[1, 1] * y + K[1, 2] - cv
        rho = math.sqrt(du * du + dv * dv)
        a = annuli[pixel[n]]
        inside = True
        if a >= 0:
            a = min(a, rings)
            inner = radii[a - 1] if a > 0 else -np.inf
            outer = radii[a] if a < rings else np.inf
            inside = inner - margin <= rho <= outer + margin
        angle = angles[pixel[n]]
        aligned = True
        if np.isfinite(angle) and rho >= _ANGLE_MIN_RADIUS_PX:
            # float32's polynomial atan2 (1e-7 rad) is ample against a limit of a tenth of a radian
            turned = abs(float(atan2(np.float32(dv), np.float32(du))) - angle)  # both within one turn
            turned = 2 * math.pi - turned if turned > math.pi else turned
            aligned = turned <= max_turn
        agree[n] = inside and aligned


@njit(nogil=True, cache=True, inline="always")
def _distorted(x: float, y: float, dist: np.ndarray) -> tuple[float, float]:
    """rig.geometry.CameraModel._distort of one point: Brown-Conrady k1, k2, p1, p2, k3."""
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y


@njit(**KERNEL)
def band_counts(
    owner: np.ndarray, agree: np.ndarray, counts: tuple[np.ndarray, np.ndarray], start: int, stop: int
) -> None:
    """Each face's pixels among [start:stop] (`owner`: each pixel's face) added to counts[0] (faces,),
    and those off the bands they read (`agree` False) to counts[1]."""
    area, off = counts
    for p in range(start, stop):
        area[owner[p]] += 1
        if not agree[p]:
            off[owner[p]] += 1


@njit(**KERNEL)
def settle(
    listed: tuple[np.ndarray, np.ndarray],
    found: tuple[np.ndarray, np.ndarray],
    counts: tuple[np.ndarray, np.ndarray],
    max_disagreement: float,
    images: tuple[np.ndarray, np.ndarray, np.ndarray],
    start: int,
    stop: int,
) -> int:
    """Which of the listed pixels [start:stop] (listed: flat pixels and their faces) keep their point
    (rig.pipeline.raster.settled_pixels, for rig.pipeline.surface.surface_on_faces). found: (ok,
    agree): whether a point was found and lies in the band its pixel read. With band_counts'
    `counts` (empty: no band test), `agree` is cleared in place for every pixel of a face with more
    than `max_disagreement` of its pixels off their bands (the face bridges an edge its corners
    miss), and `ok` &= it. Then into images (flat grid (H*W, 3), valid, triangle): a kept pixel is
    valid with its face, the others' points NaN.
    Returns how many found pixels the band test turned away."""
    pixel, owner = listed
    ok, agree = found
    area, off = counts
    grid, valid, triangle = images
    tested, dropped = len(area) > 0, 0
    for n in range(start, stop):
        f, p = owner[n], pixel[n]
        if tested:
            agree[n] = agree[n] and not off[f] > max_disagreement * area[f]
            if ok[n] and not agree[n]:
                dropped += 1
            ok[n] = ok[n] and agree[n]
        if ok[n]:
            valid[p], triangle[p] = True, f
        else:
            grid[p, 0] = grid[p, 1] = grid[p, 2] = np.nan
    return dropped
