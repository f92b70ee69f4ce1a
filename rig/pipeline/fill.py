"""The surface where no triangle between two rings reaches though rings enclose it: holes between two
rings where triangles were dropped, and the inner disc inside the innermost ring where that ring
does not close around it (where it does, rig.pipeline.disc_fill fills it across).

Such a pixel has read its annulus (between rings a-1 and a, or inside ring 0), so its point lies
on its ray between those two rings' cones. Its neighbourhood is the ring samples near it in the
image, of those two rings only, on one surface (samples farther apart in space than a steep slope
allows for their distance in the image lie on two surfaces; the slope allowed grows as the nearest
sample turns from the camera, so that a limb turning away stays one surface). A quadratic height
field is fitted to their positions and normals (each sample gives a height and two slopes; a small
ridge on the bends leaves a tangent plane where a single straight ring cannot show a bend across
it), and the pixel's ray meets it. The point is kept only if it lies in the pixel's own annulus and
near the polar angle it read (rig.pipeline.surface.band_agreement). Where samples of two surfaces
both reach a pixel (the gap at a depth step, between the last ring on one side and the first on the
other) nothing says on which side of the step the pixel lies: it stays a hole, and is reported as
one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter

from rig.geometry import CameraModel
from rig.kernels import bounds
from rig.lazy import lazy_module
from rig.workers import batches, pool

fill_kernels = lazy_module("rig.kernels.fill")  # numba compiles on first use
cell_kernels = lazy_module("rig.kernels.cells")

_CELL_PX = 8.0  # the neighbour search's cells: a few samples each, about a ring's spacing
# each ring's own cells: wider, so that rings x cells stay small (a look at an empty cell is a
# cache miss); 16 px searched fastest of 8 to 24 on the default bench
_RING_CELL_PX = 16.0
_MAX_RING_CELLS = 1_000_000  # rings x cells of their own grids (8 MB of run starts)
_PIXELS_AT_ONCE = 1 << 14  # pixels filled together: their neighbourhoods take 8 MB, not 35 for all at once


@dataclass(frozen=True)
class FillSettings:
    neighbours: int = 16  # ring samples near a pixel considered for its fit, half from each of its rings
    reach_px: float = 48.0  # no pixel farther than this from a sample of its rings is filled
    min_samples: int = 4  # samples on the pixel's surface a fit needs
    steep_stretch: float = 3.0  # samples this many footprints apart per pixel of image lie on two surfaces ...
    min_facing: float = 0.25  # ... footprints stretched by 1 / cos(slant) of the nearest sample, to this at most
    bend_ridge: float = 0.05  # ridge on the bends, relative to the fit's own scale
    max_misfit_px: float = 2.0  # samples straying from their fit by more (rms, in footprints) span two surfaces

    def __post_init__(self) -> None:
        if self.neighbours < 2:  # half from each ring: none at all from either would test neither's reach
            raise ValueError(f"FillSettings.neighbours must be at least 2, half from each ring: got {self.neighbours}")


def fill_candidates(covered: np.ndarray, annulus: np.ndarray, lit: np.ndarray | None) -> np.ndarray:
    """Flat pixels that read an annulus, are lit and are not covered by a triangle."""
    candidate = ~covered.ravel() & (annulus.ravel() >= 0)
    if lit is not None:
        candidate &= lit.ravel()
    return np.flatnonzero(candidate)


def fill_points(
    points: np.ndarray,
    normals: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    pixel: np.ndarray,
    annulus: np.ndarray,
    settings: FillSettings,
) -> np.ndarray:
    """A point (N, 3) for each flat camera pixel `pixel` that reads `annulus` (N,), NaN where no
    neighbourhood on one surface of its two rings reaches it; from samples (points, unit normals
    toward the camera, sub-pixel image positions, ring indices) of triangles already kept."""
    found = np.full((len(pixel), 3), np.nan)
    if len(points) < settings.min_samples or len(pixel) == 0:
        return found
    samples = (points, normals, xy, ring, _footprints(points, normals, camera, settings))
    grid = _search_grid(xy, ring, int(annulus.max(initial=0)) + 1)
    shape = (camera.height, camera.width)
    reached = np.flatnonzero(_rings_reach(xy, ring, pixel, shape, annulus, settings.reach_px))
    positions = _positions(pixel[reached], camera.width)
    for start in range(0, len(reached), _PIXELS_AT_ONCE):  # a block's neighbourhoods, not the whole fill's
        part, at = reached[start : start + _PIXELS_AT_ONCE], positions[start : start + _PIXELS_AT_ONCE]
        rows, met = _filled_block(samples, camera, (pixel[part], at, annulus[part]), settings, grid)
        found[part[rows]] = met
    return found


def _filled_block(
    samples: tuple[np.ndarray, ...],
    camera: CameraModel,
    pixels: tuple[np.ndarray, np.ndarray, np.ndarray],
    settings: FillSettings,
    grid: SearchGrid,
) -> tuple[np.ndarray, np.ndarray]:
    """fill_points for a block of pixels (flat pixels, their positions and annuli), from the samples
    (points, normals, xy, ring, footprints): which of them were filled, and their points. Its
    neighbourhoods are freed on return, before the next block's are made."""
    points, normals, xy, ring, footprint = samples
    pixel, positions, annulus = pixels
    dist, index = _neighbourhoods(xy, ring, positions, annulus, settings, grid)
    use = _one_surface(points, footprint, xy, ring, (dist, index), annulus, settings)
    rows = np.flatnonzero(use.sum(axis=1) >= settings.min_samples)
    if len(rows) == 0:
        return rows, np.empty((0, 3))
    origins, directions = camera.pixel_rays
    # by index: np.take would first copy a pinhole's origins, a broadcast, whole
    rays = (np.asarray(origins[pixel[rows]]), np.asarray(directions[pixel[rows]]))
    chosen = (np.take(index, rows, axis=0), np.take(use, rows, axis=0))
    met, misfit_mm = _fit_and_meet(points, normals, *chosen, rays, settings)
    smooth = misfit_mm <= settings.max_misfit_px * camera.mm_per_px(np.nan_to_num(met))
    return rows[smooth], met[smooth]


def _rings_reach(
    xy: np.ndarray, ring: np.ndarray, pixel: np.ndarray, shape: tuple[int, int], annulus: np.ndarray, reach: float
) -> np.ndarray:
    """(N,) whether both rings of each flat pixel's annulus (ring 0 alone inside it; an image of
    `shape`) may have a sample within `reach` of it: its cell of a coarse grid over the image lies
    within a box of cells of one of each ring's samples. The test errs only toward yes: a pixel it
    turns away has no neighbourhood (rig.kernels.fill.fill_neighbourhoods finds none), and the
    search for it, a look at every empty cell within the reach, is saved (most candidates lie beyond
    a surface's last ring). Each pixel's look is compiled (rig.kernels.fill.reached)."""
    rings = int(max(ring.max(initial=-1), annulus.max(initial=0))) + 1
    xy_lo, xy_hi = bounds(xy)
    corner, far = np.minimum(xy_lo, 0.0), np.maximum(xy_hi, np.array(shape[::-1]) - 1.0)
    cell = cell_kernels.group_cell_side(np.array([corner, far]), rings, _RING_CELL_PX, _MAX_RING_CELLS)
    home = ((xy - corner) // cell).astype(np.int64)
    occupied = np.zeros((rings, *((far - corner) // cell).astype(np.int64)[::-1] + 1), bool)
    occupied[ring, home[:, 1], home[:, 0]] = True
    within = int(np.ceil(reach / cell))  # a pixel within reach of a sample lies this many cells from it at most
    near = maximum_filter(occupied, size=(1, 2 * within + 1, 2 * within + 1), mode="constant", cval=False)
    reached = np.empty(len(pixel), bool)
    fill_kernels.reached(pixel, annulus, (shape[1], float(corner[0]), float(corner[1]), cell), near, reached)
    return reached


SearchGrid = tuple[np.ndarray, np.ndarray, tuple[object, object], float]


def _search_grid(xy: np.ndarray, ring: np.ndarray, rings: int) -> SearchGrid:
    """The samples as the neighbour search takes them: positions (float64), each ring's count (of
    `rings` at least), their grid of cells all together and ring by ring, and the ring cells' side."""
    xy = np.ascontiguousarray(xy, np.float64)
    members = np.bincount(ring, minlength=rings).astype(np.int64)
    ring_cell = cell_kernels.group_cell_side(xy, len(members), _RING_CELL_PX, _MAX_RING_CELLS)  # wider for many rings
    cells = (
        cell_kernels.sample_cells(xy, _CELL_PX),
        cell_kernels.group_cells(xy, ring.astype(np.int64), len(members), ring_cell),
    )
    return xy, members, cells, ring_cell


def _neighbourhoods(
    xy: np.ndarray,
    ring: np.ndarray,
    at: np.ndarray,
    annulus: np.ndarray,
    settings: FillSettings,
    grid: SearchGrid | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2k) distances (inf beyond the reach, for a sample listed already, or everywhere for a
    pixel its two rings do not both reach) and sample indices (0 there) of each pixel's `k` nearest
    samples of any ring, then of its annulus' rings (k / 2 each): the first tell whether another
    surface is in reach, the others join the fit, an equal share from each ring however much closer
    one of them runs (at a limb, or where one ring ends, the nearest of all would be of one ring
    only). A grid of cells (`grid`: _search_grid's, where made already) and a compiled search
    (rig.kernels.fill.fill_neighbourhoods), a span of pixels per thread."""
    k, reach = settings.neighbours, float(settings.reach_px)
    _, members, cells, ring_cell = grid or _search_grid(xy, ring, int(annulus.max(initial=0)) + 1)
    arrays = (members, cells, ring.astype(np.int64), np.ascontiguousarray(at), annulus.astype(np.int64))
    dist, index = np.empty((len(at), 2 * k)), np.empty((len(at), 2 * k), np.int64)

    def search(span: tuple[int, int]) -> None:
        fill_kernels.fill_neighbourhoods(*arrays, (k, reach, _CELL_PX, ring_cell), dist, index, *span)

    list(pool().map(search, batches(len(at))))
    return dist, index


def _positions(pixel: np.ndarray, width: int) -> np.ndarray:
    """(N, 2) image positions (x, y) of flat pixels."""
    return np.column_stack([pixel % width, pixel // width]).astype(np.float64)


def _footprints(points: np.ndarray, normals: np.ndarray, camera: CameraModel, settings: FillSettings) -> np.ndarray:
    """(M,) the millimetres a pixel spans at each sample, stretched by 1 / the cosine of its slant
    from the camera (to 1 / settings.min_facing at most): a surface turned away from the camera
    stretches over fewer pixels."""
    orthographic = camera.projection == "orthographic"
    to_camera = np.broadcast_to(-camera.axis, points.shape) if orthographic else camera.center - points
    facing = np.abs(np.einsum("ij,ij->i", normals, to_camera)) / np.linalg.norm(to_camera, axis=1)
    return camera.mm_per_px(points) / np.maximum(facing, settings.min_facing)


def _one_surface(
    points: np.ndarray,
    footprint: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    neighbourhood: tuple[np.ndarray, np.ndarray],
    annulus: np.ndarray,
    settings: FillSettings,
) -> np.ndarray:
    """(N, k) which neighbours (dist, index: _neighbourhoods) a pixel's fit uses: samples of its two
    rings, on the surface of its nearest such sample (samples farther apart in space than
    `settings.steep_stretch` times the sample's `footprint` (_footprints) per pixel of image lie on
    two surfaces); none at all where any sample in reach (of any ring) lies on another surface. None
    either where they are not of both its rings (but inside ring 0): such a pixel lies beyond a
    surface's last ring, and extrapolating there (a limb the projector grazes) errs by far more than
    interpolating does, so it is left a hole. A compiled pass (rig.kernels.fill.one_surface)."""
    dist, index = neighbourhood
    use = np.empty(index.shape, dtype=bool)
    arrays = (np.ascontiguousarray(points, np.float64), np.ascontiguousarray(xy, np.float64), ring.astype(np.int64))
    terms = (footprint, (dist, index), annulus.astype(np.int64), float(settings.steep_stretch))

    def judge(span: tuple[int, int]) -> None:
        fill_kernels.one_surface(*arrays, *terms, use, *span)

    list(pool().map(judge, batches(len(index))))
    return use


def _fit_and_meet(
    points: np.ndarray,
    normals: np.ndarray,
    index: np.ndarray,
    use: np.ndarray,
    rays: tuple[np.ndarray, np.ndarray],
    settings: FillSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, the weighted quadratic height field of its used samples (positions and slopes, in a
    frame along their mean normal: rig.kernels.fill) met by its ray (origins, unit directions), NaN
    where it misses; and the rms of the samples' heights off the fit (mm). Samples of two levels
    joined by a step fit a ramp between them, which their own slopes contradict: the heights stray
    by millimetres."""
    count = len(index)
    coef, frame = np.empty((count, 6)), np.empty((count, 3, 3))
    origin, misfit = np.empty((count, 3)), np.empty(count)
    arrays = (np.ascontiguousarray(points, np.float64), np.ascontiguousarray(normals, np.float64))
    index, use = np.ascontiguousarray(index, np.int64), np.ascontiguousarray(use, np.bool_)

    def fit(span: tuple[int, int]) -> None:
        fill_kernels.fit_height_fields(*arrays, index, use, settings.bend_ridge, coef, frame, origin, misfit, *span)

    list(pool().map(fit, batches(count)))
    return _meet(coef, frame, origin, rays), misfit


def _meet(coef: np.ndarray, frame: np.ndarray, origin: np.ndarray, rays: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Where each ray meets its height field h(x, y) = c0 + c1 x + c2 y + c3 x^2 + c4 x y + c5 y^2:
    the root of a quadratic in the distance along the ray nearest the tangent plane's."""
    a = np.einsum("nij,nj->ni", frame, rays[0] - origin)
    b = np.einsum("nij,nj->ni", frame, rays[1])
    c0, c1, c2, c3, c4, c5 = coef.T
    quad = c3 * b[:, 0] ** 2 + c4 * b[:, 0] * b[:, 1] + c5 * b[:, 1] ** 2
    lin = c1 * b[:, 0] + c2 * b[:, 1] + 2 * c3 * a[:, 0] * b[:, 0] + c4 * (a[:, 0] * b[:, 1] + a[:, 1] * b[:, 0])
    lin += 2 * c5 * a[:, 1] * b[:, 1] - b[:, 2]
    const = c0 + c1 * a[:, 0] + c2 * a[:, 1] + c3 * a[:, 0] ** 2 + c4 * a[:, 0] * a[:, 1] + c5 * a[:, 1] ** 2 - a[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        plane = -const / lin
        root = np.sqrt(lin**2 - 4 * quad * const)
        t1, t2 = (-lin + root) / (2 * quad), (-lin - root) / (2 * quad)
    nearer = np.where(np.abs(t1 - plane) < np.abs(t2 - plane), t1, t2)
    t = np.where(np.abs(quad) * np.abs(plane) ** 2 < 1e-9 * np.abs(const) + 1e-12, plane, nearer)
    t = np.where(np.isfinite(t) & (t > 0), t, np.nan)
    return rays[0] + t[:, None] * rays[1]
