"""Rehearsing a ring set on the pilot: what the surface between those rings would err by.

An error model from curvature alone (the sagitta bound) says how a linear interpolant errs on a
smooth patch; it says nothing of where the surface folds away from the projector (its limb), where
rings a few pixels apart lie centimetres apart on the surface, nor of the interpolant actually
configured. The pilot is a dense scan of the same object, so the rings can be tried on it instead:
cut the pilot's surface at each ring's radius (where its projector radius crosses the ring between
two neighbouring camera pixels, as the ring codec finds a ring), interpolate the surface between
those samples exactly as a ring scan would (rig.pipeline.surface, with the annulus and angle each
pixel would read), and measure the distance to the pilot's own points, pixel by pixel.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from rig.evaluate import MIN_REGION_SHARE, STEP_MM, between_rings, footprints, image_rows, region_errors
from rig.geometry import CameraModel
from rig.pipeline import Interpolant, RingBands, SurfaceSettings, interpolate_surface
from rig.progress import ProgressTracker

# Smoothing scale of the pilot's noise (camera pixels): a few pixels, far under any ring spacing.
_SMOOTH_PX = 1.5

# Neighbouring pixels further apart than this many pixel footprints straddle a depth edge: no ring
# sample between them (the codec drops such crossings as jumps).
_JUMP_FOOTPRINTS = 6.0


@dataclass(frozen=True, eq=False)
class PilotSurface:
    """A pilot's points organised on its camera's pixel grid, with their projector polar coordinates
    and, per point, the area it stands for and its region (rig.evaluate.regions)."""

    grid: np.ndarray  # (H, W, 3), NaN where the pilot has no point
    camera: CameraModel
    projector: CameraModel
    rho: np.ndarray  # (H, W) projector radius about the rings' centre, NaN where no point
    theta: np.ndarray  # (H, W) projector polar angle
    footprint_mm: np.ndarray  # (H, W) millimetres one camera pixel spans at each point's depth
    area_mm2: np.ndarray  # (H, W) surface area each point stands for, 0 where no point
    region: np.ndarray  # (H, W) region label (regions split at depth steps), -1 where no point

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.rho)


@dataclass(frozen=True)
class Rehearsal:
    """How a ring set would do on the pilot, by area: the distance (mm) of the interpolated surface
    to the pilot's points as rms and as the quantile `quantile` of the area over the whole view and
    over its worst region (each region split off by a depth step that holds at least
    MIN_REGION_SHARE of the area), and, of the area the rings promise a surface at
    (rig.evaluate.promise.between_rings), the share the surface covers on its least covered region."""

    rings: int
    rms_mm: float
    quantile_mm: float
    worst_region_mm: float
    covered: float
    quantile: float = 0.95

    def meets(self, tolerance_mm: float, min_covered: float) -> bool:
        return self.worst_region_mm <= tolerance_mm and self.covered >= min_covered

    def as_dict(self) -> dict[str, float | int]:
        return {
            "rings": self.rings,
            "rms_mm": round(self.rms_mm, 4),
            "quantile": self.quantile,
            "quantile_mm": round(self.quantile_mm, 4),
            "worst_region_mm": round(self.worst_region_mm, 4),
            "covered": round(self.covered, 4),
        }


def pilot_surface(
    grid: np.ndarray, camera: CameraModel, projector: CameraModel, center_px: tuple[float, float], step: int = 1
) -> PilotSurface:
    """The pilot on every `step`-th camera row and column (a camera of 1/step the resolution sees
    them: rehearsals are step^2 times cheaper, and the rings' spacing is what they test)."""
    grid = smoothed(grid, camera)
    if step > 1:
        grid = grid[::step, ::step]
        scale = np.diag([1.0 / step, 1.0 / step, 1.0])
        camera = dataclasses.replace(camera, width=grid.shape[1], height=grid.shape[0], K=scale @ camera.K)
    valid = np.isfinite(grid).all(axis=2)
    uv, z = projector.project(np.where(valid[..., None], grid, 0.0).reshape(-1, 3))
    du, dv = uv[:, 0] - center_px[0], uv[:, 1] - center_px[1]
    seen = valid.ravel() & (z > 0)
    rho = np.where(seen, np.hypot(du, dv), np.nan).reshape(valid.shape)
    theta = np.where(seen, np.arctan2(dv, du), np.nan).reshape(valid.shape)
    valid = np.isfinite(rho)
    footprint = _footprint_mm(grid, camera)
    areas, labels = footprints(grid, valid, np.maximum(STEP_MM, _JUMP_FOOTPRINTS * np.nan_to_num(footprint)))
    area, region = np.zeros(valid.shape), np.full(valid.shape, -1)
    area[valid], region[valid] = areas, labels
    return PilotSurface(grid, camera, projector, rho, theta, footprint, area, region)


def smoothed(grid: np.ndarray, camera: CameraModel, sigma_px: float = _SMOOTH_PX) -> np.ndarray:
    """The pilot with its noise along the rays averaged down (a Gaussian of the distance along each
    ray over valid neighbours; a pixel whose average lands far from it, by an edge, keeps its own):
    the ring samples cut from it, and the normals the interpolant takes from them, should be about
    as clean as a ring scan's, whose ring edges are located more finely than a dense code's pixels."""
    origins, directions = camera.pixel_rays
    shape = grid.shape[:2]
    flat = grid.reshape(-1, 3)
    along = np.einsum("ij,ij->i", flat - origins, directions).reshape(shape)
    valid = np.isfinite(along)
    weight = cv2.GaussianBlur(valid.astype(np.float32), (0, 0), sigma_px)
    total = cv2.GaussianBlur(np.where(valid, along, 0.0).astype(np.float32), (0, 0), sigma_px)
    mean = total / np.maximum(weight, 1e-6)
    footprint = np.abs(along) / camera.K[0, 0] if camera.projection == "pinhole" else 1.0 / camera.K[0, 0]
    keep = valid & (np.abs(mean - along) <= _JUMP_FOOTPRINTS * footprint)
    along = np.where(keep, mean, along).reshape(-1)
    return (origins + along[:, None] * directions).reshape(grid.shape)


def organised(points: np.ndarray, camera: CameraModel) -> np.ndarray:
    """Points of a dense scan put back on the camera pixels they were seen at (nearest pixel;
    the nearer point where two land on one)."""
    grid = np.full((camera.height, camera.width, 3), np.nan)
    uv, z = camera.project(points)
    col, row = np.rint(uv[:, 0]).astype(np.int64), np.rint(uv[:, 1]).astype(np.int64)
    inside = (z > 0) & (col >= 0) & (col < camera.width) & (row >= 0) & (row < camera.height)
    order = np.flatnonzero(inside)[np.argsort(-z[inside])]  # far first: the nearest is written last
    grid[row[order], col[order]] = points[order]
    return grid


def annuli(pilot: PilotSurface, radii: np.ndarray) -> np.ndarray:
    """The annulus (between rings a-1 and a) of every pilot pixel, -1 where the pilot has no point."""
    return np.where(pilot.valid, np.searchsorted(radii, np.nan_to_num(pilot.rho, nan=-1.0)), -1)


def ring_samples(
    pilot: PilotSurface, radii: np.ndarray, annulus: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each ring crosses the pilot's surface between horizontally or vertically neighbouring
    pixels: 3D points, sub-pixel camera positions and ring indices (`annulus`: annuli(), if known)."""
    if annulus is None:
        annulus = annuli(pilot, radii)
    footprint = pilot.footprint_mm
    # A ring scan finds no sample at the end of a ring stretch (its pixels straddle the boundary:
    # rig.pipeline.ring_triangulation.along_ring_support) nor at the frame's border; the pilot's own pixels
    # there are its least reliable, and their normals would bend whole triangles.
    inside = cv2.erode(pilot.valid.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    found: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    height, width = annulus.shape
    for dy, dx in ((0, 1), (1, 0)):
        a = (slice(0, height - dy), slice(0, width - dx))
        b = (slice(dy, height), slice(dx, width))
        za, zb = annulus[a], annulus[b]
        cross = inside[a] & inside[b] & (np.abs(za - zb) == 1)
        ya, xa = np.nonzero(cross)
        pa, pb = pilot.grid[a][ya, xa], pilot.grid[b][ya, xa]
        near = np.linalg.norm(pb - pa, axis=1) <= _JUMP_FOOTPRINTS * footprint[a][ya, xa]
        ya, xa, pa, pb = ya[near], xa[near], pa[near], pb[near]
        ring = np.minimum(za[ya, xa], zb[ya, xa])
        ra, rb = pilot.rho[a][ya, xa], pilot.rho[b][ya, xa]
        t = np.clip((radii[ring] - ra) / (rb - ra), 0.0, 1.0)
        xy = np.column_stack([xa + t * dx, ya + t * dy]).astype(np.float64)
        found.append((pa + t[:, None] * (pb - pa), xy, ring))
    points, xy, ring = (np.concatenate(parts) for parts in zip(*found, strict=True))
    return points, xy, ring


def _footprint_mm(grid: np.ndarray, camera: CameraModel) -> np.ndarray:
    """Millimetres one camera pixel spans at each point's depth."""
    if camera.projection == "orthographic":
        return np.full(grid.shape[:2], 1.0 / camera.K[0, 0])
    depth = camera.to_device(np.nan_to_num(grid).reshape(-1, 3))[:, 2].reshape(grid.shape[:2])
    return np.abs(depth) / camera.K[0, 0]


def rehearse(
    pilots: list[PilotSurface],
    radii: np.ndarray,
    center_px: tuple[float, float],
    method: Interpolant,
    noise_mm: float = 0.0,
    quantile: float = 0.95,
) -> Rehearsal:
    """The rings `radii` cut out of each pilot view and interpolated, against the pilot, by area
    (see Rehearsal), less the pilot's own noise (`noise_mm`, which the comparison counts once more
    than the ring scan will; what stays stands for the ring scan's own noise)."""
    radii = np.asarray(radii, dtype=np.float64)
    dist, area, label, promised = [], [], [], []
    for view, pilot in enumerate(pilots):
        covered, measured, d, judged = _distances(pilot, radii, center_px, method)
        dist.append(d)
        area.append(pilot.area_mm2[measured])
        label.append(pilot.region[measured] * len(pilots) + view)  # each view's regions its own
        polar = image_rows(pilot.rho, pilot.theta)
        within = between_rings(polar, pilot.region, pilot.area_mm2, pilot.valid, radii) & judged
        promised.append((pilot.region[within] * len(pilots) + view, pilot.area_mm2[within], covered[within]))
    d, a = np.concatenate(dist), np.concatenate(area)
    if len(d) == 0 or a.sum() <= 0:
        return Rehearsal(len(radii), float("inf"), float("inf"), float("inf"), 0.0, quantile)
    whole, regions = region_errors(d, a, np.concatenate(label), quantile)

    def less_noise(value: float) -> float:
        return math.sqrt(max(0.0, value**2 - noise_mm**2))

    worst = max((r.quantile_mm for r in regions), default=whole.quantile_mm)
    return Rehearsal(
        len(radii), less_noise(whole.rms_mm), less_noise(whole.quantile_mm), less_noise(worst),
        _worst_coverage(promised), quantile,
    )  # fmt: skip


def _worst_coverage(promised: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> float:
    """The least share covered of any region's promised area, of the regions holding
    MIN_REGION_SHARE of all that is promised or more; per view, each promised pixel's region (numbered
    apart from the other views'), area and whether the surface covers it."""
    if not promised:
        return 0.0
    region, area, covered = (np.concatenate(column) for column in zip(*promised, strict=True))
    total = np.bincount(region, area)
    got = np.bincount(region, area * covered, minlength=len(total))
    judged = total >= MIN_REGION_SHARE * max(total.sum(), 1e-12)
    return float((got[judged] / total[judged]).min()) if judged.any() else 0.0


def _distances(
    pilot: PilotSurface, radii: np.ndarray, center_px: tuple[float, float], method: Interpolant
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which pilot pixels the rings' surface covers (H, W), which of them are measured (H, W), its
    distance to the pilot there, and which pixels are judged at all (H, W). A flank the surface
    keeps (rig.pipeline.flanks) is covered, not measured: the pilot's dense code sees it as
    foreshortened as the rings do, and there errs by more than they (a sphere's limb at 97 rings:
    0.2 mm off the pilot, 0.03 mm off the truth)."""
    annulus = annuli(pilot, radii)
    points, xy, ring = ring_samples(pilot, radii, annulus)
    valid = pilot.valid
    bands = RingBands(annulus.astype(np.int16), pilot.theta.astype(np.float32), radii, center_px)
    # The pilot is smoothed already: its samples' normals need no averaging along the rings.
    settings = SurfaceSettings(normal_smoothing_px=0.0)
    surface = interpolate_surface(points, xy, ring, pilot.camera, pilot.projector, valid, method, settings, bands)
    # The pilot's own pixels at its edges are its least reliable (a dense code mixes the two sides):
    # they are not what a ring scan is measured against.
    inner = cv2.erode(valid.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    covered = surface.valid & inner
    flank = np.zeros(len(surface.faces) + 1, dtype=bool)  # the last for "no face" (a filled pixel)
    if surface.flank is not None:
        flank[:-1] = surface.flank
    measured = covered & ~flank[surface.triangle]
    return covered, measured, np.linalg.norm(surface.grid[measured] - pilot.grid[measured], axis=1), inner


def noise_mm(pilot: PilotSurface) -> float:
    """The pilot's noise along the camera rays, from second differences of range along the rows
    (robust: a smooth surface adds little to them, edges are outliers): var(d2) = 6 sigma^2."""
    distance = np.linalg.norm(pilot.grid - pilot.camera.center, axis=2)
    d2 = distance[:, :-2] - 2.0 * distance[:, 1:-1] + distance[:, 2:]
    d2 = d2[np.isfinite(d2)]
    if len(d2) < 100:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def rehearsal_progress(tracker: ProgressTracker, start: float) -> Callable[[Rehearsal], None]:
    """Each rehearsal of a plan's search reported as stage `plan`, from `start` ever nearer the end
    (a search's length is not known ahead), with the ring count and its rms."""
    count = itertools.count(1)

    def rehearsed(found: Rehearsal) -> None:
        k = next(count)
        message = f"rehearsal {k}: {found.rings} rings, worst region {found.worst_region_mm:.3f} mm"
        tracker.report("plan", 1.0 - (1.0 - start) * 0.9**k, message)

    return rehearsed
