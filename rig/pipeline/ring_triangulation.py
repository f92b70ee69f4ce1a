"""Ring samples -> points: ray-cone triangulation, root choice by angle (or radius and fine angle
together, rig.pipeline.ring_angles), conditioning masks, the depth-edge tests along and across
rings, coverage, and normals from a triangulation of the samples."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from rig.geometry import CameraModel, parallel_projection, radius_ratio, ray_cone, refine_on_distorted_ring
from rig.patterns import Correspondence, RingSamples
from rig.pipeline.dense import texture_rgb
from rig.pipeline.normals import accumulate_normals
from rig.pipeline.pointset import PointSet
from rig.pipeline.ring_angles import Placed, place_by_fine_angle
from rig.pipeline.triangulation import delaunay

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
    angle_error = np.abs(np.angle(np.exp(1j * (hits.theta - samples.theta[:, None]))))
    angle_error[~np.isfinite(s)] = np.inf
    choice = np.argmin(angle_error, axis=1)
    rows = np.arange(len(choice))
    found = angle_error[rows, choice] <= MAX_ANGLE_ERROR_RAD
    s_chosen = s[rows, choice]
    s_other = s[rows, 1 - choice]
    points = origins + s_chosen[:, None] * directions
    other = origins + s_other[:, None] * directions
    if samples.model != "cone":  # the dissertation's closed forms; the cone still gives conditioning
        points = _closed_form(samples.model, camera, projector, samples)
        other = np.full_like(points, np.nan)
        found &= np.isfinite(points).all(axis=1)
    sigma = np.abs(hits.ds_dradius[rows, choice]) * samples.radius_sigma_px
    cos_beta = np.nan_to_num(hits.cos_beta[rows, choice], nan=0.0)
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
    result = RingPoints(*(column[found] for column in columns), contrast=samples.contrast[found])
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
    # The ring index as a third coordinate far apart keeps neighbours on their own ring.
    coords = np.column_stack([rings.camera_xy[kept], rings.ring[kept] * 10.0 * reach_px])
    pairs = cKDTree(coords).query_pairs(reach_px, output_type="ndarray")
    support = np.zeros(len(kept), np.int64)
    offset_sum = np.zeros((len(kept), 2))
    reach_sum = np.zeros(len(kept))
    if len(pairs):
        close = pairs[np.abs(depth[pairs[:, 0]] - depth[pairs[:, 1]]) <= max_jump_mm]
        offset = coords[close[:, 1], :2] - coords[close[:, 0], :2]
        length = np.linalg.norm(offset, axis=1)
        for end, sign in ((0, 1.0), (1, -1.0)):
            np.add.at(support, close[:, end], 1)
            np.add.at(offset_sum, close[:, end], sign * offset)
            np.add.at(reach_sum, close[:, end], length)
    # An end of a ring stretch (at a shadow, an occlusion or a depth edge) has its neighbours on one
    # side only: its pixels straddle the boundary and may see the far surface.
    one_sided = np.linalg.norm(offset_sum, axis=1) > _ONE_SIDED * np.maximum(reach_sum, 1e-9)
    out = np.zeros(len(rings.kept), bool)
    out[kept[(support >= min_support) & ~one_sided]] = True
    return out


def _plane_agrees(
    dx: np.ndarray,
    dy: np.ndarray,
    z: np.ndarray,
    depth: np.ndarray,
    use: np.ndarray,
    max_jump_mm: float,
    min_count: int,
    max_scatter_mm: float = np.inf,
) -> np.ndarray:
    """For each point, whether the plane z = a + b dx + c dy fitted to its neighbours (offsets `dx`,
    `dy` in pixels, depths `z`, (N, K)) where `use` predicts its depth (the plane's `a`) within
    `max_jump_mm` or four times the fit's scatter; False where fewer than `min_count` neighbours
    support it or the fit scatters more than `max_scatter_mm` (no plane: two surfaces, which a
    plane would interpolate between)."""
    w = use.astype(np.float64)
    sums = [np.sum(w * term, axis=1) for term in (1.0, dx, dy, dx * dx, dx * dy, dy * dy, z, dx * z, dy * z)]
    n, sx, sy, sxx, sxy, syy, sz, sxz, syz = sums
    normal = np.stack([np.stack([n, sx, sy], 1), np.stack([sx, sxx, sxy], 1), np.stack([sy, sxy, syy], 1)], 1)
    coef = np.linalg.solve(normal + 1e-6 * np.eye(3), np.stack([sz, sxz, syz], 1)[..., None])[..., 0]
    fitted = coef[:, :1] + coef[:, 1:2] * dx + coef[:, 2:3] * dy
    scatter = np.sqrt(np.sum(w * (z - fitted) ** 2, axis=1) / np.maximum(n - 3, 1))
    allowed = np.maximum(max_jump_mm, 4.0 * scatter)
    return (n >= min_count) & (scatter <= max_scatter_mm) & (np.abs(depth - coef[:, 0]) <= allowed)


def across_ring_support(
    rings: RingPoints, camera: CameraModel, max_jump_mm: float, neighbours: int = 24, min_count: int = 6
) -> np.ndarray:
    """Mask of kept ring points that the neighbouring rings agree with. A stretch of a ring that took
    a wrong index at a depth edge agrees with itself (so the along-ring test keeps it) but lies
    between the two surfaces. The nearest samples of other rings are split at the largest gap in
    their depths (the two sides of an edge, or two halves of one surface), and a plane is fitted to
    all of them (if they lie on one plane) and to each part: a point no fit predicts is rejected.
    Points whose neighbours come from one other ring only (a curve: a plane through it
    extrapolates) are left alone. Run it twice: once the worst are gone, the fits see clearly."""
    kept = np.flatnonzero(rings.kept)
    out = rings.kept.copy()
    if len(kept) <= neighbours:
        return out
    # Neighbouring rings lie farther off than a ring's own samples: a plane over them misses a
    # curved surface by more, so only a gross disagreement (a ring stretch on the wrong surface,
    # many millimetres off) counts.
    max_jump_mm = ACROSS_RINGS_FACTOR * max_jump_mm
    xy = rings.camera_xy[kept]
    depth = (rings.points[kept] - camera.center) @ camera.axis
    ring = rings.ring[kept]
    # Candidates: every 4th sample, so a point's own ring (a sample a pixel) does not crowd out the
    # other rings among its nearest, and the fits span a wider patch.
    candidates = np.arange(0, len(kept), 4)
    k = min(len(candidates), 2 * neighbours)
    _, nearest = cKDTree(xy[candidates]).query(xy, k, workers=-1)
    index = candidates[nearest]
    other = ring[index] != ring[:, None]
    # the nearest `neighbours` samples of other rings, packed to the front (stable: nearest first)
    order = np.argsort(~other, axis=1, kind="stable")[:, :neighbours]
    index = np.take_along_axis(index, order, axis=1)
    use = np.take_along_axis(other, order, axis=1)
    near_ring = ring[index]
    judged = np.where(use, near_ring, np.iinfo(ring.dtype).max).min(axis=1) < np.where(
        use, near_ring, np.iinfo(ring.dtype).min
    ).max(axis=1)
    dx, dy = xy[index, 0] - xy[:, :1], xy[index, 1] - xy[:, 1:]
    z = depth[index]
    agrees = _plane_agrees(dx, dy, z, depth, use, max_jump_mm, min_count, max_scatter_mm=0.5 * max_jump_mm)
    doubt = np.flatnonzero(judged & ~agrees)  # on a smooth patch the one plane settles it
    if len(doubt):
        dx, dy, z, d, u = dx[doubt], dy[doubt], z[doubt], depth[doubt], use[doubt]
        ordered = np.sort(np.where(u, z, np.nan), axis=1)  # NaN last
        gaps = np.diff(ordered, axis=1)
        split_at = np.argmax(np.where(np.isfinite(gaps), gaps, -np.inf), axis=1)
        rows = np.arange(len(doubt))
        threshold = 0.5 * (ordered[rows, split_at] + ordered[rows, split_at + 1])
        below = u & (z <= threshold[:, None])
        near = near_ring[doubt]
        either = np.zeros(len(doubt), bool)
        for part in (below, u & ~below):
            # samples of one ring alone lie on a curve, which fixes no plane: such a side cannot judge
            one_ring = np.where(part, near, np.iinfo(near.dtype).max).min(axis=1) == np.where(
                part, near, np.iinfo(near.dtype).min
            ).max(axis=1)
            either |= _plane_agrees(dx, dy, z, d, part, max_jump_mm, min_count) | (part.any(axis=1) & one_ring)
        agrees[doubt] = either
    out[kept[judged & ~agrees & (use.sum(axis=1) >= min_count)]] = False
    return out


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
    tri = delaunay(camera_xy) if tri is None else tri
    if len(tri):
        xy = camera_xy[tri]
        longest = np.max(np.linalg.norm(xy - np.roll(xy, 1, axis=1), axis=2), axis=1)
        tri = tri[longest <= max_edge_px]
    p = points[tri]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # area-weighted
    facing = np.einsum("ij,ij->i", face, directions[tri[:, 0]]) > 0
    face[facing] *= -1
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
    keep = np.flatnonzero(rings.kept)
    points = rings.points[keep]
    xy = rings.camera_xy[keep]
    normals = sample_normals(points, xy, rings.directions[keep], _MAX_TRIANGLE_EDGE_PX, tri)
    col = np.clip(np.rint(xy[:, 0]).astype(np.int64), 0, camera.width - 1)
    row = np.clip(np.rint(xy[:, 1]).astype(np.int64), 0, camera.height - 1)
    pixel = row * camera.width + col
    rgb = texture_rgb(corr).reshape(-1, 3)
    cloud = PointSet(
        points=points,
        normals=normals.astype(np.float32),
        colors=rgb[pixel],
        quality=rings.cos_beta[keep].astype(np.float32),
        source=np.full(len(keep), source, np.uint8),
        pixel=pixel,
    )
    return cloud
