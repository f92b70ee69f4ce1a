"""The fast path from a dense correspondence to a cloud: one pair's cloud as camera images (an
organised cloud: each pixel's distance along its ray, its depth, colour and quality, and the kept
pixels' normals), computed a band of rows per thread from per-pixel terms the pair computes once;
the PointSet and the stored scan are built from it afterwards.

It computes what rig.pipeline.dense computes (PairTriangulator.triangulate, reject_isolated,
grid_normals, texture_rgb), in float32 and relative to the camera centre, each step one pass of a
compiled loop (rig.kernels.dense) per band of rows, and live mode's depth image of coded planes all
its steps in one (rig.kernels.depth): points agree within float32 rounding of the stored
coordinates. It covers a pinhole camera and a pinhole projector without distortion coding one axis
(without skew across it: a ray meets a plane) or both (radial, Gray code both ways: a ray meets a
ray); other pairs take the general path.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np

from rig.geometry import CameraModel
from rig.lazy import lazy_module
from rig.patterns import Correspondence
from rig.pipeline.dense import PairTriangulator, texture_rgb
from rig.pipeline.pointset import PointSet
from rig.workers import in_row_strips

kernels = lazy_module("rig.kernels.dense")  # numba compiles on first use: not for --help
depth_kernels = lazy_module("rig.kernels.depth")

_MIN_SUPPORT = 3  # as reject_isolated: neighbours within the depth-jump limit a point needs
_NORMAL_STEP = 2  # as grid_normals: neighbours this many pixels away span the tangent plane


Images = np.ndarray  # (H, W), written a band of rows at a time
_EMPTY = np.empty(0, np.float32)  # what a used-up cloud's images are


@dataclass(eq=False)
class OrganisedCloud:
    """One pair's cloud as camera images (H, W): each pixel's point is ray * direction relative to
    the camera centre `origin` (the pair's unit ray `directions`, (3, H, W), kept with its terms),
    NaN where `valid` is False; the normals of the valid pixels only, in row-major order (as the
    PointSet holds them). One float32 image of ray parameters instead of three of coordinates."""

    origin: np.ndarray  # (3,) float64, world mm
    ray: np.ndarray  # (H, W) float32: the point's distance along its pixel's unit ray
    directions: np.ndarray  # (3, H, W) float32: the pixels' unit rays (shared, not the cloud's)
    depth: np.ndarray  # (H, W) float32: distance along the camera axis, NaN where not decoded
    normals: np.ndarray  # (N, 3) float32, unit, facing the camera: the valid pixels', row by row
    valid: np.ndarray  # (H, W) bool
    first: np.ndarray  # (H + 1,) int64: row y's valid pixels are normals[first[y]:first[y + 1]]
    colours: np.ndarray  # (H, W, 3) uint8 RGB
    quality: np.ndarray  # (H, W) float32
    used: bool = False  # into_pointset has taken the images

    def grid(self) -> np.ndarray:
        """World points (H, W, 3) float64, NaN where not valid (PairResult.grid)."""
        grid = np.moveaxis(self.directions * self.ray, 0, -1).astype(np.float64)
        grid += self.origin  # in place: one (H, W, 3) array, not two
        return grid

    def into_pointset(self, source: int) -> PointSet:
        """The cloud's PointSet, built by using the cloud up: its points, pixels, colours and
        quality are gathered at the valid pixels by one compiled pass, its normals are the cloud's
        own, and the images are let go. The cloud is empty after."""
        if self.used:
            raise RuntimeError("this organised cloud was already made into its PointSet")
        self.used = True
        count = len(self.normals)
        points, pixel = np.empty((count, 3), np.float32), np.empty(count, np.int32)
        colors, quality = np.empty((count, 3), np.uint8), np.empty(count, np.float32)
        images = (np.ascontiguousarray(self.colours), np.ascontiguousarray(self.quality))
        in_row_strips(
            len(self.ray),
            lambda rows: kernels.kept_points(
                self.ray, self.directions, self.valid, self.first, self.origin, *images,
                (points, pixel, colors, quality), rows.start, rows.stop,
            ),
        )  # fmt: skip
        self.ray = self.depth = self.valid = self.colours = self.quality = _EMPTY
        normals, self.normals = self.normals, _EMPTY
        source_index = np.full(count, source, dtype=np.uint8)
        return PointSet(points, normals, colors, quality, source_index, pixel)


class PixelTerms(abc.ABC):
    """Per-pixel terms of a pair computed once: each camera pixel's unit ray and its component along
    the camera axis (for depth jumps), float32; subclasses triangulate what they code."""

    def __init__(self, camera: CameraModel) -> None:
        shape = (camera.height, camera.width)
        directions = camera.pixel_rays[1]
        self.directions = np.ascontiguousarray(directions.T.astype(np.float32)).reshape(3, *shape)
        self.along_axis = (directions @ camera.axis).astype(np.float32).reshape(shape)

    @abc.abstractmethod
    def triangulate(self, corr: Correspondence, ray: Images, depth: Images, decoded: Images, rows: slice) -> None:
        """Rows `rows` of each pixel's distance along its ray, its depth and whether it has a point
        (rig.kernels.dense writes them in place)."""

    def depth(self, corr: Correspondence, max_jump_mm: float | None) -> tuple[np.ndarray, int]:
        """organised_depth: triangulated, isolated points dropped, the depth blanked where none is
        kept, a pass each."""
        _, depth, keep, _ = _triangulated(self, corr, max_jump_mm)
        kept: list[int] = []
        in_row_strips(
            depth.shape[0], lambda rows: kept.append(kernels.blank_unkept(depth, keep, rows.start, rows.stop))
        )
        return depth, sum(kept)


class PlaneTerms(PixelTerms):
    """A pair whose camera ray meets the plane of a projector column (or row) x: the ray parameter
    is s = (a + b x) / (c + d x), c and d float32 (H, W); a and b are the same at every pixel (the
    camera's rays all leave its centre), so they are two numbers, not two images to read."""

    def __init__(
        self, camera: CameraModel, axis: str, terms: tuple[np.ndarray, ...], scale: float, shift: float
    ) -> None:
        """`terms`: PairTriangulator's plane terms (nd_a, nd_b, no_a, no_b, c0, c1) of a camera whose
        rays all leave its centre (no_a and no_b the same at every pixel); x normalised = scale *
        coded + shift."""
        super().__init__(camera)
        self.axis = axis
        nd_a, nd_b, no_a, no_b, c0, c1 = terms
        no_a, no_b = np.atleast_1d(no_a), np.atleast_1d(no_b)
        if not (np.allclose(no_a, no_a[0], rtol=1e-12, atol=0) and np.allclose(no_b, no_b[0], rtol=1e-12, atol=0)):
            raise ValueError("plane terms of a camera whose rays leave from more than one point")
        shape = (camera.height, camera.width)
        # s = (c0 - no_a + (c1 - no_b) x) / (nd_a + nd_b x), with x = scale * coded + shift
        self.a = np.float32(c0 - no_a[0] + (c1 - no_b[0]) * shift)
        self.b = np.float32((c1 - no_b[0]) * scale)
        self.c = (nd_a + nd_b * shift).astype(np.float32).reshape(shape)
        self.d = (nd_b * scale).astype(np.float32).reshape(shape)
        self.scale, self.shift = np.float32(scale), np.float32(shift)

    def triangulate(self, corr: Correspondence, ray: Images, depth: Images, decoded: Images, rows: slice) -> None:
        kernels.plane_triangulate(
            self._coded(corr), corr.valid, (self.a, self.b), self.c, self.d, self.scale, self.shift,
            self.along_axis, ray, depth, decoded, rows.start, rows.stop,
        )  # fmt: skip

    def depth(self, corr: Correspondence, max_jump_mm: float | None) -> tuple[np.ndarray, int]:
        """organised_depth in one pass per band of rows, no ray image or masks (rig.kernels.depth):
        the same depths."""
        coded, shape = self._coded(corr), corr.valid.shape
        depth, kept = np.empty(shape, np.float32), []
        plane = (coded, corr.valid, (self.a, self.b, self.scale, self.shift), self.c, self.d, self.along_axis)
        isolation = (max_jump_mm is not None, np.float32(max_jump_mm or 0.0), _MIN_SUPPORT)
        in_row_strips(
            shape[0],
            lambda rows: kept.append(depth_kernels.plane_depth(plane, isolation, depth, rows.start, rows.stop)),
        )
        return depth, sum(kept)

    def _coded(self, corr: Correspondence) -> np.ndarray:
        coded = corr.u if self.axis == "u" else corr.v
        assert coded is not None
        return coded


class RayRayTerms(PixelTerms):
    """A pair with both projector coordinates decoded (radial, or Gray code in both directions): the
    point of each camera ray closest to the projector ray of (u, v), PairTriangulator._ray_ray_fast
    per pixel from the camera's rays and the projector's 3x3 map from (u, v, 1) to its ray."""

    def __init__(self, camera: CameraModel, projector: CameraModel) -> None:
        super().__init__(camera)
        self.to_ray = projector.R.T @ np.linalg.inv(projector.K)
        self.offset = np.asarray(camera.center - projector.center, np.float64)

    def triangulate(self, corr: Correspondence, ray: Images, depth: Images, decoded: Images, rows: slice) -> None:
        assert corr.u is not None and corr.v is not None
        kernels.ray_ray_triangulate(
            corr.u, corr.v, corr.valid, self.directions, self.to_ray, self.offset,
            self.along_axis, ray, depth, decoded, rows.start, rows.stop,
        )  # fmt: skip


def fast_terms(triangulator: PairTriangulator, coded: str) -> PixelTerms | None:
    """The pair's terms for a code of the axes `coded` ("u", "v" or "uv"; computed once, kept with
    the triangulator), or None where the pair needs the general path: a projector with distortion
    (or, for one axis, skew), a camera whose rays do not all leave its centre."""
    projector, camera = triangulator.projector, triangulator.camera
    if projector.projection != "pinhole" or camera.projection != "pinhole":
        return None
    if projector.has_distortion if coded == "uv" else not triangulator.planes_affine(coded):
        return None
    key = f"pixel_terms_{coded}"
    if key not in triangulator.derived:
        if coded == "uv":
            triangulator.derived[key] = RayRayTerms(camera, projector)
        else:
            K = projector.K
            focal, centre = (K[0, 0], K[0, 2]) if coded == "u" else (K[1, 1], K[1, 2])
            terms = triangulator.plane_terms(coded)
            triangulator.derived[key] = PlaneTerms(camera, coded, terms, 1.0 / focal, -centre / focal)
    found = triangulator.derived[key]
    assert isinstance(found, PixelTerms)
    return found


def organised_cloud(
    terms: PixelTerms, origin: np.ndarray, corr: Correspondence, max_jump_mm: float | None
) -> tuple[OrganisedCloud, dict[str, int]]:
    """Triangulate, drop isolated points (depth jumps over `max_jump_mm`, None: none dropped),
    normals and colours; the counts as reconstruct_pair reports them."""
    ray, depth, keep, counts = _triangulated(terms, corr, max_jump_mm)
    height = keep.shape[0]
    first = np.zeros(height + 1, np.int64)  # row y's kept pixels are normals[first[y]:first[y + 1]]
    np.cumsum(np.count_nonzero(keep, axis=1), out=first[1:])
    normals = np.empty((int(first[-1]), 3), np.float32)
    in_row_strips(
        height,
        lambda rows: kernels.kept_normals(
            ray, terms.directions, _NORMAL_STEP, keep, first, normals, rows.start, rows.stop
        ),
    )
    cloud = OrganisedCloud(origin, ray, terms.directions, depth, normals, keep, first, texture_rgb(corr), corr.quality)
    return cloud, counts


def organised_depth(terms: PixelTerms, corr: Correspondence, max_jump_mm: float | None) -> tuple[np.ndarray, int]:
    """The depth image alone (H, W) float32 in mm, NaN where organised_cloud keeps no point: what
    live mode shows, without the normals and colours a cloud carries; and the points it has."""
    return terms.depth(corr, max_jump_mm)


def _triangulated(
    terms: PixelTerms, corr: Correspondence, max_jump_mm: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """Ray parameters and depths (H, W), the points kept (isolated ones dropped), and the counts."""
    height, width = corr.valid.shape
    ray, depth = np.empty((height, width), np.float32), np.empty((height, width), np.float32)
    decoded = np.empty((height, width), bool)
    in_row_strips(height, lambda rows: terms.triangulate(corr, ray, depth, decoded, rows))
    counts: dict[str, int] = {}
    keep = decoded
    if max_jump_mm is not None:
        keep, jump, dropped = np.empty_like(decoded), np.float32(max_jump_mm), []
        in_row_strips(
            height,
            lambda rows: dropped.append(
                kernels.reject_isolated(depth, decoded, jump, _MIN_SUPPORT, keep, ray, rows.start, rows.stop)
            ),
        )
        counts["rejected_depth_jump"] = sum(dropped)
    return ray, depth, keep, counts
