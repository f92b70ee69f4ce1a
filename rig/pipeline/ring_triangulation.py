"""Ring samples -> points: ray-cone triangulation, root choice by angle (or radius and fine angle
together, rig.pipeline.ring_angles), conditioning masks, the depth-edge tests along and across
rings, coverage, and normals from a triangulation of the samples."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.geometry import CameraModel, parallel_projection, radius_ratio, ray_cone, refine_on_distorted_ring
from rig.kernels import bounds, kept_rows
from rig.lazy import lazy_module
from rig.patterns import Correspondence, RingSamples
from rig.pipeline.dense import texture_rgb
from rig.pipeline.normals import accumulate_normals
from rig.pipeline.pointset import PointSet
from rig.pipeline.ring_angles import Placed, place_by_fine_angle
from rig.pipeline.triangulation import delaunay
from rig.workers import batches, pool

ring_kernels = lazy_module("rig.kernels.rings")  # numba compiles on first use: not for --help
point_kernels = lazy_module("rig.kernels.ring_points")
across_kernels = lazy_module("rig.kernels.across")
cell_kernels = lazy_module("rig.kernels.cells")
normal_kernels = lazy_module("rig.kernels.normals")

# Triangles of the sample mesh longer than this (camera pixels) bridge gaps, not neighbouring rings.
_MAX_TRIANGLE_EDGE_PX = 80.0

# A sample whose agreeing neighbours along its ring sum to an offset more than this fraction of their
# total distance has them all on one side: the end of a ring stretch.
_ONE_SIDED = 0.75

# The across-ring test rejects only this many times the depth-jump limit off the neighbours' plane.
ACROSS_RINGS_FACTOR = 5.0

# A root whose projector angle is further than this from the decoded angle is not the ring point:
# when neither root is this close, the sample is rejected.
MAX_ANGLE_ERROR_RAD = 0.6


@dataclass(frozen=True, eq=False)
class RingPoints:
    """Triangulated ring samples. `kept` marks the points that pass the conditioning masks; the
    other arrays cover every sample that had a valid root."""

    points: np.ndarray  # (M, 3) the chosen root, or where radius and fine angle agree
    other_root: np.ndarray  # (M, 3) the rejected root, NaN if there was one root only
    origins: np.ndarray  # (M, 3) camera ray of each sample
    directions: np.ndarray  # (M, 3)
    camera_xy: np.ndarray  # (M, 2)
    ring: np.ndarray  # (M,)
    sigma_mm: np.ndarray  # (M,) displacement for the codec's assumed radius (and fine angle) errors
    cos_beta: np.ndarray  # (M,)
    kept: np.ndarray  # (M,) bool
    contrast: np.ndarray  # (M,)


def triangulate_rings(
    camera: CameraModel, projector: CameraModel, samples: RingSamples
) -> tuple[RingPoints, dict[str, int]]:
    """Each sample's point: the root of its ray and ring cone that the coarse angle picks, or, with
    the fine angular code, the point radius and fine angle agree on (which also places the samples
    where the ring runs along the epipolar line); the closed-form models where configured."""
    origins, directions = camera.rays(samples.camera_xy)
    origins = np.ascontiguousarray(origins)
    hits = ray_cone(projector, origins, directions, samples.radius_px, samples.center_px)
    s = hits.s
    if projector.has_distortion:
        ring = (samples.radius_px, samples.center_px)
        s = np.column_stack(
            [refine_on_distorted_ring(projector, origins, directions, s[:, k], *ring) for k in range(2)]
        )
    # Choose the root whose projector angle matches the decoded angular code.
    count = len(samples)
    found, sigma, cos_beta = np.empty(count, bool), np.empty(count), np.empty(count)
    points, other = np.empty((count, 3)), np.empty((count, 3))
    arrays = (
        (s, hits.theta, hits.ds_dradius, hits.cos_beta),
        np.asarray(samples.theta, np.float64),
        (origins, np.ascontiguousarray(directions, np.float64)),
        (float(samples.radius_sigma_px), MAX_ANGLE_ERROR_RAD),
        (found, points, other, sigma, cos_beta),
    )
    list(pool().map(lambda span: point_kernels.chosen_roots(*arrays, *span), batches(count)))
    if samples.model != "cone":  # the dissertation's closed forms; the cone still gives conditioning
        points = _closed_form(samples.model, camera, projector, samples)
        other = np.full_like(points, np.nan)
        found &= np.isfinite(points).all(axis=1)
    near_centre = samples.radius_px < samples.min_radius_px
    ill_conditioned = cos_beta < samples.min_cos_beta
    counts: dict[str, int] = {"ring_samples": len(samples)}
    if samples.fine_phase is not None and samples.model == "cone":
        fine = np.isfinite(samples.fine_phase)
        ill_conditioned &= ~fine  # the angle fixes these points
        placed = Placed(found, points, other, sigma, cos_beta)
        counts.update(
            place_by_fine_angle(projector, origins, directions, samples, hits, s, np.flatnonzero(fine), placed)
        )
    kept = found & ~near_centre & ~ill_conditioned
    rejected_by_angle = counts.get("rejected_angle_misfit", 0) + counts.get("rejected_angle_ambiguous", 0)
    counts.update(
        {
            "rejected_no_root": int((~found).sum()) - rejected_by_angle,
            "masked_near_centre": int((found & near_centre).sum()),
            "masked_ill_conditioned": int((found & ~near_centre & ill_conditioned).sum()),
            "ring_points": int(kept.sum()),
        }
    )
    columns = (points, other, origins, directions, samples.camera_xy, samples.ring, sigma, cos_beta, kept)
    result = RingPoints(*kept_rows(found, *columns), contrast=samples.contrast[found])
    return result, counts


def along_ring_support(
    rings: RingPoints, camera: CameraModel, max_jump_mm: float, reach_px: float = 3.0, min_support: int = 2
) -> np.ndarray:
    """Mask of kept ring points with at least `min_support` samples of the same ring within
    `reach_px` in the image whose depth is within `max_jump_mm`: the sparse codec's counterpart of
    the dense depth-jump filter. A sample on a depth edge (its ring half on each surface) decodes to
    neither surface and agrees with no neighbour; a point of a surface has one on each side."""
    kept = np.flatnonzero(rings.kept)
    if len(kept) < 2:
        return rings.kept.copy()
    depth = (rings.points[kept] - camera.center) @ camera.axis
    xy = np.ascontiguousarray(rings.camera_xy[kept], np.float64)
    cells = cell_kernels.sample_cells(xy, float(reach_px))
    support, offset_length, reach_sum = np.empty(len(kept), np.int64), np.empty(len(kept)), np.empty(len(kept))
    arrays = (
        xy,
        rings.ring[kept].astype(np.int64),
        np.ascontiguousarray(depth),
        cells,
        (float(reach_px), float(max_jump_mm)),
    )
    outputs = (support, offset_length, reach_sum)
    list(pool().map(lambda span: ring_kernels.along_support(*arrays, *outputs, *span), batches(len(kept))))
    # An end of a ring stretch (at a shadow, an occlusion or a depth edge) has its neighbours on one
    # side only: its pixels straddle the boundary and may see the far surface.
    one_sided = offset_length > _ONE_SIDED * np.maximum(reach_sum, 1e-9)
    out = np.zeros(len(rings.kept), bool)
    out[kept[(support >= min_support) & ~one_sided]] = True
    return out


def across_ring_support(
    rings: RingPoints,
    camera: CameraModel,
    max_jump_mm: float,
    neighbours: int = 24,
    min_count: int = 6,
    passes: int = 2,
) -> np.ndarray:
    """Mask of kept ring points that the neighbouring rings agree with. A stretch of a ring that took
    a wrong index at a depth edge agrees with itself (so the along-ring test keeps it) but lies
    between the two surfaces. The nearest samples of other rings are split at the largest gap in
    their depths (the two sides of an edge, or two halves of one surface), and a plane is fitted to
    all of them (if they lie on one plane) and to each part: a point no fit predicts is rejected.
    Points whose neighbours come from one other ring only (a curve: a plane through it
    extrapolates) are left alone. It runs `passes` times over the same neighbourhoods, each without
    the points the passes before rejected: once the worst are gone, the fits see clearly. Each
    point is judged in compiled code (rig.kernels.across): a neighbourhood's planes are fitted once
    for the samples that share it, in registers, not (points, neighbours) arrays."""
    kept = np.flatnonzero(rings.kept)
    out = rings.kept.copy()
    if len(kept) <= neighbours:
        return out
    xy = rings.camera_xy[kept]
    depth = (rings.points[kept] - camera.center) @ camera.axis
    ring = rings.ring[kept]
    candidates = _every_fourth_along_rings(xy, ring)
    index, row, anchors = _nearest_candidates(xy, ring, candidates, min(len(candidates), 2 * neighbours))
    alive = np.ones(len(kept), bool)
    points = (np.ascontiguousarray(xy, np.float64), np.ascontiguousarray(depth, np.float64), ring.astype(np.int64))
    limits = (ACROSS_RINGS_FACTOR * max_jump_mm, neighbours, min_count)
    for _ in range(passes):
        judged = np.flatnonzero(alive)
        agrees = _agrees(points, (index, row, anchors, alive), judged, limits)
        alive[judged[~agrees]] = False
    out[kept[~alive]] = False
    return out


def _every_fourth_along_rings(xy: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Every 4th sample along each ring (about a pixel apart), in ascending order: the across-ring
    test's candidates, so that a point's own ring does not crowd out the other rings among its
    nearest and the fits span a wider patch. Along a ring is by angle about the centroid of its
    samples in the image; every sample then lies within ~2 px of a candidate of its ring and shares
    that candidate's neighbourhood (the samples' own order runs across the image, leaving a fifth of
    them with no candidate of their ring within reach, each a search of its own)."""
    count = np.maximum(np.bincount(ring), 1)
    centre_x = np.bincount(ring, xy[:, 0]) / count
    centre_y = np.bincount(ring, xy[:, 1]) / count
    along = np.arctan2(xy[:, 1] - centre_y[ring], xy[:, 0] - centre_x[ring])
    return cell_kernels.every_nth_by_group(ring.astype(np.int64), along, len(count), 4)


# A sample within this of a candidate of its ring (pixels) takes the candidate's nearest candidates.
_SHARED_NEIGHBOURHOOD_PX = 3.0
# Each ring's own grid of candidates (for the one nearest a sample) has cells this wide: a grid per
# ring of cells as fine as the reach would be larger than the image's pixels.
_OWN_RING_CELL_PX = 16.0


def _nearest_candidates(
    xy: np.ndarray, ring: np.ndarray, candidates: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The `k` candidates nearest each sample, nearest first: (R, k) rows of them, each sample's
    row (N,) and each row's own sample's xy (R, 2). A sample within _SHARED_NEIGHBOURHOOD_PX of a
    candidate of its own ring takes that candidate's row (its fits span ~50 px): the k nearest are
    searched for the candidates, and for the samples without one near. A grid of cells 1.5 times
    the candidates' mean spacing wide (the fastest of 0.7 to 4 on the default bench), searched in
    compiled code (rig.kernels.cells.k_nearest), a span of samples per thread; a sample's own
    ring's candidate in each ring's own grid of cells."""
    xy = np.ascontiguousarray(xy, np.float64)
    spots = np.ascontiguousarray(xy[candidates])
    ring = ring.astype(np.int64)
    groups = int(ring.max(initial=0)) + 1
    side = cell_kernels.group_cell_side(spots, groups, _OWN_RING_CELL_PX)
    own_cells = cell_kernels.group_cells(spots, ring[candidates], groups, side)
    dist, closest = np.empty((len(xy), 1)), np.empty((len(xy), 1), np.int64)
    where = (side, _SHARED_NEIGHBOURHOOD_PX)
    list(
        pool().map(
            lambda span: cell_kernels.k_nearest_in_group(own_cells, where, xy, ring, dist, closest, *span),
            batches(len(xy)),
        )
    )
    shared = np.isfinite(dist[:, 0])  # a candidate of its ring nearer than the reach
    shared[candidates] = False  # a candidate is searched for itself
    closest = candidates[np.maximum(closest[:, 0], 0)]
    lo, hi = bounds(spots)
    cell = max(1.5 * np.sqrt(np.prod(hi - lo + 1.0) / len(spots)), 1.0)  # ~2 candidates a cell
    cells = cell_kernels.sample_cells(spots, cell)
    searched = np.flatnonzero(~shared)
    row = np.empty(len(xy), np.int64)
    row[searched] = np.arange(len(searched))
    row[shared] = row[closest[shared]]  # a candidate, searched
    anchors = np.ascontiguousarray(xy[searched])
    return candidates[_k_nearest(cells, cell, anchors, k)], row, anchors


def _k_nearest(cells: tuple[object, ...], cell: float, at: np.ndarray, k: int) -> np.ndarray:
    """(N, k) indices of the `k` points of `cells` nearest each of `at` (rig.kernels.cells.k_nearest)."""
    index = np.empty((len(at), k), np.int64)
    list(pool().map(lambda span: cell_kernels.k_nearest(cells, cell, at, index, *span), batches(len(at))))
    return index


def _agrees(
    points: tuple[np.ndarray, ...],
    neighbourhoods: tuple[np.ndarray, ...],
    judged: np.ndarray,
    limits: tuple[float, int, int],
) -> np.ndarray:
    """rig.kernels.across.across_agrees over the pool: each judged point's verdict, the points taken
    neighbourhood by neighbourhood (`neighbourhoods`: rows of candidates, every point's row, each
    row's own sample's xy, which points are alive)."""
    by_row = cell_kernels.group_order(neighbourhoods[1][judged], len(neighbourhoods[2]))[0]  # stable, by counting
    ordered, verdicts = judged[by_row], np.empty(len(judged), bool)
    arrays = (points, neighbourhoods, ordered, limits, verdicts)
    list(pool().map(lambda span: across_kernels.across_agrees(*arrays, *span), batches(len(judged))))
    agrees = np.empty(len(judged), bool)
    agrees[by_row] = verdicts
    return agrees


def _closed_form(model: str, camera: CameraModel, projector: CameraModel, samples: RingSamples) -> np.ndarray:
    if model == "parallel":
        return parallel_projection(
            camera, projector, samples.camera_xy, samples.radius_px, samples.theta, samples.center_px
        )
    if model == "radius_ratio":
        return radius_ratio(camera, projector, samples.camera_xy, samples.radius_px, samples.center_px)
    raise ValueError(f"unknown ring model {model!r}")


def sample_normals(
    points: np.ndarray, camera_xy: np.ndarray, directions: np.ndarray, max_edge_px: float, tri: np.ndarray | None = None
) -> np.ndarray:
    """Unit normals of scattered surface samples, from a Delaunay triangulation of their camera
    positions (which links neighbouring rings); triangles with an image edge longer than
    `max_edge_px` are dropped. Oriented toward the camera; samples in no triangle face the camera."""
    tri = np.ascontiguousarray(delaunay(camera_xy) if tri is None else tri, np.int64)
    arrays = tuple(np.ascontiguousarray(a, np.float64) for a in (points, camera_xy, directions))
    face, short = np.empty((len(tri), 3)), np.empty(len(tri), np.bool_)
    list(
        pool().map(
            lambda span: normal_kernels.area_faces(*arrays, tri, float(max_edge_px), face, short, *span),
            batches(len(tri)),
        )
    )
    tri, face = kept_rows(short, tri, face)
    return accumulate_normals(tri, face, directions)


def ring_coverage(rings: RingPoints, samples: RingSamples, min_samples: int = 50) -> dict[str, object]:
    """The fraction of each ring's length seen in the camera (its samples, about one a pixel) that
    became points: overall, the least of any ring with `min_samples` samples or more, and per ring."""
    seen = np.bincount(samples.ring)
    kept = np.bincount(rings.ring[rings.kept], minlength=len(seen))
    judged = np.flatnonzero(seen >= min_samples)
    per_ring = {int(k): round(float(kept[k] / seen[k]), 4) for k in judged}
    return {
        "overall": round(float(kept.sum() / max(1, seen.sum())), 4),
        "min_ring": min(per_ring.values()) if per_ring else None,
        "rings": per_ring,
    }


def ring_pointset(
    rings: RingPoints, camera: CameraModel, corr: Correspondence, source: int, tri: np.ndarray | None = None
) -> PointSet:
    """The PointSet of the kept ring points (normals from their triangulation, colour of the lit
    frame at the nearest pixel, `pixel` that nearest pixel: PairResult.grid and the depth maps
    place each point there, with no (H, W, 3) grid held for a few ten thousand points)."""
    columns = (rings.points, rings.camera_xy, rings.directions, rings.cos_beta)
    points, xy, directions, cos_beta = kept_rows(rings.kept, *columns)
    normals = sample_normals(points, xy, directions, _MAX_TRIANGLE_EDGE_PX, tri)
    col = np.clip(np.rint(xy[:, 0]).astype(np.int64), 0, camera.width - 1)
    row = np.clip(np.rint(xy[:, 1]).astype(np.int64), 0, camera.height - 1)
    pixel = row * camera.width + col
    rgb = texture_rgb(corr).reshape(-1, 3)
    cloud = PointSet(
        points=points,
        normals=normals.astype(np.float32),
        colors=np.take(rgb, pixel, axis=0),
        quality=cos_beta.astype(np.float32),
        source=np.full(len(points), source, np.uint8),
        pixel=pixel,
    )
    return cloud
