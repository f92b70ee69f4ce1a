"""The ring surface's triangles (rig.pipeline.ring_faces, rig.pipeline.raster), compiled by numba: the
tests every image triangle of the ring samples meets, and the camera pixels each kept one covers.
As numpy passes over (triangles, 3) arrays these took a dozen passes each; here one loop per
triangle computes what they did, in the same floating-point order."""

from __future__ import annotations

import numpy as np
from numba import njit

from rig.kernels import KERNEL
from rig.kernels.vectors import corner_cross, row_distance

KEPT, RING_SKIPPED, GAP, ONE_RING = 0, 1, 2, 3  # a triangle's verdict on the rings it joins


@njit(**KERNEL)
def triangle_tests(
    tri: np.ndarray,
    ring: np.ndarray,
    camera_xy: np.ndarray,
    projector_xy: np.ndarray,
    points: np.ndarray,
    directions: np.ndarray,
    depths: np.ndarray,
    lengths: tuple[float, float, float],
    verdict: np.ndarray,
    face: np.ndarray,
    weight: np.ndarray,
    slant: np.ndarray,
    foreshortened: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """Per triangle [start:stop] of `tri` (F, 3) of the samples (ring index, image positions in the camera and the
    projector, points, camera rays, depths (M, 2) in the camera and the projector, 1 for an
    orthographic device): its `verdict` (KEPT: joins one ring to the next with no edge along a
    ring longer than the gap; else why not) and, whatever it, its unit normal toward the camera
    `face`, 1 / its longest edge in mm `weight`, |cos| of the normal with corner 0's ray `slant`,
    and `foreshortened`: how foreshortened its edge that both devices see most foreshortened is,
    the least over its edges of f_camera x f_projector, where f = (image length x mm per pixel at
    its depth) / 3D length is the cosine of the edge's tilt out of a device's image plane
    (rig.pipeline.flanks). lengths: (max gap px, camera focal px, projector focal px)."""
    max_gap, camera_focal, projector_focal = lengths
    edge_mm = np.empty(3)
    for f in range(start, stop):
        a, b, c = tri[f, 0], tri[f, 1], tri[f, 2]
        low, high = min(ring[a], ring[b], ring[c]), max(ring[a], ring[b], ring[c])
        gap = False
        least = np.inf
        for k in range(3):
            i, j = tri[f, k], tri[f, (k + 1) % 3]
            edge_px = np.sqrt((camera_xy[j, 0] - camera_xy[i, 0]) ** 2 + (camera_xy[j, 1] - camera_xy[i, 1]) ** 2)
            gap = gap or (ring[i] == ring[j] and edge_px > max_gap)
            edge_mm[k] = row_distance(points, i, j)
            along_px = np.sqrt(
                (projector_xy[j, 0] - projector_xy[i, 0]) ** 2 + (projector_xy[j, 1] - projector_xy[i, 1]) ** 2
            )
            # each device: (image length x mm per pixel at the edge's middle) / length, the cosine of its tilt
            length = max(edge_mm[k], 1e-12)
            seen = 1.0 * min(1.0, edge_px * (0.5 * (depths[i, 0] + depths[j, 0]) / camera_focal) / length)
            seen *= min(1.0, along_px * (0.5 * (depths[i, 1] + depths[j, 1]) / projector_focal) / length)
            least = min(least, seen)
        span = high - low
        verdict[f] = RING_SKIPPED if span > 1 else ONE_RING if span == 0 else GAP if gap else KEPT
        foreshortened[f] = least
        weight[f] = 1.0 / max(max(edge_mm[0], edge_mm[1], edge_mm[2]), 1e-9)
        nx, ny, nz = _face_normal(points, directions, a, b, c)
        face[f, 0], face[f, 1], face[f, 2] = nx, ny, nz
        slant[f] = abs(nx * directions[a, 0] + ny * directions[a, 1] + nz * directions[a, 2])


@njit(nogil=True, cache=True, inline="always")
def _face_normal(points: np.ndarray, directions: np.ndarray, a: int, b: int, c: int) -> tuple[float, float, float]:
    """A triangle's unit normal, turned toward the camera (against corner a's ray)."""
    nx, ny, nz = corner_cross(points, a, b, c)
    norm = max(np.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    if nx * directions[a, 0] + ny * directions[a, 1] + nz * directions[a, 2] > 0:
        return -nx, -ny, -nz
    return nx, ny, nz


@njit(**KERNEL)
def rasterize(xy: np.ndarray, tri: np.ndarray, image: np.ndarray, strip: tuple[int, int]) -> None:
    """rig.pipeline.raster.rasterize into rows [top, bottom) (`strip`) of `image` (H, W int32, -1
    where no triangle): each triangle's rows (corners sorted by y, ties in their order), each row's
    span between the long edge and the short edge above or below the middle corner; a later triangle
    wins a shared pixel. Every strip takes the triangles in the same order: strips on several threads
    give the image one thread gives."""
    height, width = image.shape
    strip_top, strip_bottom = strip
    image[strip_top:strip_bottom] = -1
    ys = np.empty(3)
    for f in range(len(tri)):
        order = _by_y(xy, tri[f], ys)
        x0, y0 = xy[tri[f, order[0]], 0], xy[tri[f, order[0]], 1]
        x1, y1 = xy[tri[f, order[1]], 0], xy[tri[f, order[1]], 1]
        x2, y2 = xy[tri[f, order[2]], 0], xy[tri[f, order[2]], 1]
        if not y2 > y0:
            continue  # a flat triangle has no inside
        top = min(max(np.ceil(y0), 0), height - 1)
        bottom = min(max(np.floor(y2), 0), height - 1)
        long_at, long_slope = _edge(x0, y0, x2, y2)
        upper_at, upper_slope = _edge(x0, y0, x1, y1)
        lower_at, lower_slope = _edge(x1, y1, x2, y2)
        for row in range(max(int(top), strip_top), min(int(bottom) + 1, strip_bottom)):
            x_long = long_at + row * long_slope
            x_short = lower_at + row * lower_slope if row > y1 else upper_at + row * upper_slope
            first = int(min(max(np.ceil(min(x_long, x_short)), 0), width))
            last = int(min(max(np.floor(max(x_long, x_short)), -1), width - 1))
            for column in range(first, last + 1):
                image[row, column] = f


@njit(nogil=True, cache=True, inline="always")
def _by_y(xy: np.ndarray, corners: np.ndarray, ys: np.ndarray) -> tuple[int, int, int]:
    """The corners' positions sorted by y, equal ones in their order (a stable sort of three)."""
    for k in range(3):
        ys[k] = xy[corners[k], 1]
    a, b, c = 0, 1, 2
    if ys[b] < ys[a]:
        a, b = b, a
    if ys[c] < ys[b]:
        b, c = c, b
        if ys[b] < ys[a]:
            a, b = b, a
    return a, b, c


@njit(nogil=True, cache=True, inline="always")
def _edge(xa: float, ya: float, xb: float, yb: float) -> tuple[float, float]:
    """An edge from (xa, ya) down to (xb, yb) as x = at + y * slope; a flat edge as x = xb (it is
    met only in its own row, where the other edges give its other end)."""
    dy = yb - ya
    if dy == 0:
        return xb, 0.0
    slope = (xb - xa) / dy
    return xa - ya * slope, slope


@njit(**KERNEL)
def face_areas(image: np.ndarray, lit: np.ndarray, area: np.ndarray, dark: np.ndarray, strip: tuple[int, int]) -> None:
    """Each face's pixels in rows [top, bottom) (`strip`) of a rasterised `image` (H, W, the face at
    each pixel, -1 none) added to `area` (faces,), and its dark ones (`lit` (H, W) False; an empty
    `lit`: none) to `dark`."""
    check = lit.size > 0
    for row in range(strip[0], strip[1]):
        for column in range(image.shape[1]):
            f = image[row, column]
            if f >= 0:
                area[f] += 1
                if check and not lit[row, column]:
                    dark[f] += 1


@njit(**KERNEL)
def kept_pixels(
    image: np.ndarray,
    kept: np.ndarray,
    renumber: np.ndarray,
    listed: tuple[np.ndarray, np.ndarray],
    start: int,
    strip: tuple[int, int],
) -> None:
    """The flat pixels of rows [top, bottom) (`strip`) of a rasterised `image` whose faces are `kept`,
    in row-major order, and their faces `renumber`ed, into `listed` (pixels, faces) from `start` on."""
    pixel, owner = listed
    width, n = image.shape[1], start
    for row in range(strip[0], strip[1]):
        for column in range(width):
            f = image[row, column]
            if f >= 0 and kept[f]:
                pixel[n], owner[n] = row * width + column, renumber[f]
                n += 1
