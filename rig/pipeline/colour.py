"""Colour between the rings (dissertation ch.5): colour known only along the projected curves,
interpolated over the surface.

Each ring sample takes its colour from the lit (white) frame at its own sub-pixel position: only
the pixels under the ring's curve are read. Every covered pixel of the interpolated surface then
takes a weighted mean of nearby samples, in 3D on the surface: its neighbours are the samples of
the two rings its triangle joins (the triangle was kept because it bridges no depth edge, so they
are on the pixel's own surface), on each ring the L + 2 samples nearest the triangle's corner there
(L = `neighbours`), and none farther than twice the triangle's longest edge.

- `nearest`: the mean of the L nearest of them (the dissertation's choice for uniform sampling);
- `idw`: all of them, weighted by inverse squared distance;
- `area`: inverse squared distance times the surface area each sample stands for (a third of its
  triangles' area), so that where samples crowd along a ring (rings seen obliquely, or rings
  planned close together) one ring does not outvote the other: density-compensated weights for
  non-uniform sampling.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from rig.lazy import lazy_module
from rig.pipeline.surface import RingSurface
from rig.workers import POOL_WAIT_S, batches, beside, full_on_pool, pool

colour_kernels = lazy_module("rig.kernels.colour")  # numba compiles on first use

ColourMethod = Literal["nearest", "idw", "area"]
COLOUR_METHODS: tuple[str, ...] = ("nearest", "idw", "area")

_SOFTENING_MM = 0.05  # keeps a pixel on a sample from taking an infinite weight


def sample_colours(texture: np.ndarray, xy: np.ndarray, full_scale: int) -> np.ndarray:
    """The lit frame (H, W grey, or H, W, 3 BGR) at sub-pixel positions xy (M, 2), bilinear, as
    RGB float32 in [0, 1] of full scale (M, 3)."""
    image = texture if texture.ndim == 3 else texture[..., None]
    h, w = image.shape[:2]
    x = np.clip(xy[:, 0], 0, w - 1)
    y = np.clip(xy[:, 1], 0, h - 1)
    x0, y0 = np.minimum(x.astype(np.int64), w - 2), np.minimum(y.astype(np.int64), h - 2)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = image[y0, x0] * (1 - fx) + image[y0, x0 + 1] * fx
    bottom = image[y0 + 1, x0] * (1 - fx) + image[y0 + 1, x0 + 1] * fx
    value = (top * (1 - fy) + bottom * fy) / full_scale
    rgb = value[:, ::-1] if value.shape[1] == 3 else np.repeat(value, 3, axis=1)
    return rgb.astype(np.float32)


def interpolate_colour(
    surface: RingSurface, colours: np.ndarray, method: ColourMethod = "area", neighbours: int = 8, stride: int = 1
) -> np.ndarray:
    """Colour (H, W, 3 float32) of the covered pixels of `surface` on every `stride`-th row and
    column (the mesh's vertices; NaN elsewhere), from its samples' `colours` (M, 3) by `method`
    (see the module docstring)."""
    return colour_beside_fill(surface, colours, method, neighbours, stride)(surface)


def check_colour_method(method: str) -> None:
    """ValueError naming `method` unless it is one of COLOUR_METHODS."""
    if method not in COLOUR_METHODS:
        raise ValueError(f"unknown colour interpolant {method!r}; known: {', '.join(COLOUR_METHODS)}")


@dataclass(frozen=True, eq=False)
class ColourTerms:
    """What the colour of a surface's pixels takes from its samples and faces alone (colour_terms),
    made before the surface's points are known: rig.kernels.colour.mix_colours' per-sample and
    per-face arrays (samples (3, M + 1) float32 about `centre`, area (M + 1,), colours (M + 1, 3):
    each padded with a sample that lies beyond any reach; candidates (along, corners); reach2)."""

    tree: Future[cKDTree]  # the samples' k-d tree, being built on the pool
    samples: np.ndarray
    area: np.ndarray
    colours: np.ndarray
    candidates: tuple[np.ndarray, np.ndarray]
    reach2: np.ndarray
    centre: np.ndarray  # (3,) the samples' centre, which the pixels' positions are taken about
    settings: tuple[bool, int, float]  # mix_colours': (nearest, L, softening squared)


def colour_terms(
    samples: tuple[np.ndarray, np.ndarray, np.ndarray], colours: np.ndarray, method: ColourMethod, neighbours: int
) -> ColourTerms | None:
    """The colour's terms (ColourTerms) of a surface's samples (`samples`: their points (M, 3), the
    faces (F, 3) and their rings (M,)) and their `colours`: each face's reach and corners, each
    sample's share of area and its nearest along its ring; None without faces (nothing to mix)."""
    check_colour_method(method)
    vertices, faces, ring = samples
    if len(faces) == 0:
        return None
    centre = vertices.mean(axis=0)
    # unbalanced: built in a third less time; its queries a quarter slower, and only the filled pixels ask
    tree = pool().submit(cKDTree, vertices, balanced_tree=False)
    faces, count = np.ascontiguousarray(faces, np.int64), len(vertices)
    reach2, corners, area = np.empty(len(faces), np.float32), np.empty((len(faces), 2), np.int64), np.zeros(count)
    colour_kernels.face_terms(
        np.ascontiguousarray(vertices, np.float64), faces, ring.astype(np.int64), reach2, corners, area
    )
    area = area if method == "area" else np.ones(count)
    along = _along_rings(vertices, faces, ring, neighbours)
    # float32 about the samples' centre: a few hundred mm to 1e-4 mm, ample for weights. One row per
    # coordinate; index M (no sample) lies beyond any reach.
    return ColourTerms(
        tree,
        np.hstack([(vertices - centre).T, np.full((3, 1), 1e18)]).astype(np.float32),
        np.append(area, 0.0).astype(np.float32),
        np.vstack([colours, np.zeros((1, 3), np.float32)]).astype(np.float32),
        (along, corners),
        reach2,
        centre,
        (method == "nearest", min(neighbours, 2 * along.shape[1]), _SOFTENING_MM**2),
    )


def colour_beside_fill(
    surface: RingSurface,
    colours: np.ndarray,
    method: ColourMethod = "area",
    neighbours: int = 8,
    stride: int = 1,
    begun: Future[ColourTerms | None] | None = None,
) -> Callable[[RingSurface], np.ndarray]:
    """interpolate_colour begun on a surface whose fill is yet to come (rig.pipeline.surface
    .fill_surface, which adds pixels beyond the triangles): its covered pixels are mixed on a thread
    beside the caller's (rig.workers.beside) while the caller fills. The function returned, given
    the filled surface, waits for them and gives each pixel filled beyond the triangles its nearest
    sample's colour. `begun`: colour_terms of this surface's samples, faces, `colours`, `method`
    and `neighbours`, submitted to rig.workers.beside() before this call (the thread runs its work
    in order, so they are made when the mix starts); the terms are made here otherwise."""
    check_colour_method(method)
    height, width = surface.valid.shape
    on_grid = np.zeros_like(surface.valid)
    on_grid[::stride, ::stride] = True
    pixel = np.flatnonzero((surface.valid & on_grid).ravel())  # now: the fill adds to valid
    samples = (surface.vertices, surface.faces, surface.ring)
    begun = begun or beside().submit(colour_terms, samples, colours, method, neighbours)
    mixing = beside().submit(_mixed, surface, pixel, begun)  # the terms go with the mix, before the fill ends

    def finish(filled: RingSurface) -> np.ndarray:
        out, tree = mixing.result(timeout=POOL_WAIT_S)
        at = np.flatnonzero((filled.valid & on_grid).ravel())
        at = at[filled.triangle.ravel()[at] < 0]  # filled beyond the triangles: the nearest sample's colour
        if tree is not None and len(at):
            out[at] = colours[tree.query(filled.grid.reshape(-1, 3)[at], workers=-1)[1]]
        return out.reshape(height, width, 3)

    return finish


def _mixed(
    surface: RingSurface, pixel: np.ndarray, begun: Future[ColourTerms | None]
) -> tuple[np.ndarray, cKDTree | None]:
    """The flat colour image (H*W, 3 float32) of the covered pixels `pixel` of the triangles
    (rig.kernels.colour.mix_colours passes over any filled beyond them), NaN elsewhere, and the
    samples' k-d tree for those (None for no triangles: they stay NaN)."""
    terms = begun.result(timeout=POOL_WAIT_S)  # done: made on this thread before
    height, width = surface.valid.shape
    out = full_on_pool((height * width, 3), np.nan, np.float32)
    if terms is None:
        return out, None
    owner = surface.triangle.ravel()[pixel]
    at = (surface.grid.reshape(-1, 3), pixel, owner, terms.centre)  # the points of pixels the fill leaves alone
    arrays = (terms.samples, terms.area, terms.colours, terms.candidates, terms.reach2)

    def colour_part(span: tuple[int, int]) -> None:
        colour_kernels.mix_colours(*arrays, at, terms.settings, out, *span)

    list(pool().map(colour_part, batches(len(pixel))))
    return out, terms.tree.result(timeout=POOL_WAIT_S)


def _along_rings(vertices: np.ndarray, faces: np.ndarray, ring: np.ndarray, neighbours: int) -> np.ndarray:
    """(M, L + 2) per sample, the L + 2 samples of its ring nearest it in space (M where none): a
    face's candidates are those of a corner on each of its two rings (two more than L: pixels across
    the face have other nearest ones). Only samples of a face count. An exact search that sweeps each
    ring along one of its two widest axes (rig.kernels.colour.ring_sweeps, nearest_on_ring), a span
    of samples per thread."""
    used = np.flatnonzero(np.bincount(faces.ravel(), minlength=len(vertices)) > 0)
    along = np.full((len(vertices), min(neighbours + 2, len(used))), len(vertices), np.int64)
    if len(used) == 0:
        return along
    points, used_ring = np.ascontiguousarray(vertices[used], np.float64), ring[used].astype(np.int64)
    sweeps = colour_kernels.ring_sweeps(points, used_ring, int(used_ring.max()) + 1)
    named = (used.astype(np.int64), len(vertices))

    def search(span: tuple[int, int]) -> None:
        colour_kernels.nearest_on_ring(points, used_ring, sweeps, named, along, *span)

    list(pool().map(search, batches(len(used))))
    return along
