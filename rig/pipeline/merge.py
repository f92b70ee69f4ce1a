"""One cloud from several (projector, camera) pairs: redundancy removed, density made uniform.

Every pair's points are already in the world frame. Where pairs overlap, each surface patch is
sampled by several pairs; merging keeps, near every point, only the best-conditioned pair's sample
(it does not average: samples of different pairs carry different calibration errors, and an
average of two offset surfaces is a third surface that neither measured; keeping one preserves
each point's provenance). A point is dropped when a point of another pair with a better score lies
within `radius` (twice the sampling distance); so no two kept points of different pairs are closer
than that. Then a voxel grid
of the sampling distance keeps the best point per voxel, giving one density over the object.

The score is the inverse of the expected error along the surface normal: the projector's angular
noise (one projector pixel, scaled by the decode quality) moved through the triangulation angle
and seen along the camera ray (`expected_error_mm`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from rig.geometry import CameraModel
from rig.kernels import bounds
from rig.lazy import lazy_module
from rig.pipeline.pointset import PointSet
from rig.workers import batches, point_blocks, pool

kernels = lazy_module("rig.kernels.dense")  # numba compiles on first use: not for --help

RADIUS_IN_SAMPLINGS = 2.0


@dataclass(frozen=True)
class MergeReport:
    points_in: int
    redundant_removed: int
    thinned_removed: int
    points_out: int
    sampling_mm: float  # the coarsest pair's median spacing
    radius_mm: float
    voxel_mm: float | None
    kept_per_pair: dict[int, int] = field(default_factory=dict)
    overlap_per_pair: dict[int, int] = field(default_factory=dict)  # points with another pair's within radius

    def as_dict(self) -> dict[str, object]:
        return {
            "points_in": self.points_in,
            "redundant_removed": self.redundant_removed,
            "thinned_removed": self.thinned_removed,
            "points_out": self.points_out,
            "removed_fraction": round(1 - self.points_out / max(1, self.points_in), 4),
            "sampling_mm": round(self.sampling_mm, 4),
            "radius_mm": round(self.radius_mm, 4),
            "voxel_mm": None if self.voxel_mm is None else round(self.voxel_mm, 4),
            "kept_per_pair": {str(k): v for k, v in self.kept_per_pair.items()},
            "overlap_per_pair": {str(k): v for k, v in self.overlap_per_pair.items()},
        }


def _ray_directions(model: CameraModel, points: np.ndarray) -> np.ndarray:
    """Unit directions of the device's rays through `points` (from the device to the point), in
    the points' own precision."""
    if model.projection == "orthographic":
        return np.broadcast_to(model.axis.astype(points.dtype), points.shape)
    d = points - model.center.astype(points.dtype)
    return d / np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]


def triangulation_angles(points: np.ndarray, camera: CameraModel, projector: CameraModel) -> np.ndarray:
    """Angle (degrees, float32) between the camera's and the projector's rays at each point
    (float32 throughout: a thousandth of a degree is plenty, and it halves the time); pinhole
    devices by a compiled pass a block of points per thread (rig.kernels.dense.ray_angles)."""
    out = np.empty(len(points), np.float32)
    if camera.projection == "pinhole" and projector.projection == "pinhole" and points.dtype == np.float32:
        centres = (camera.center.astype(np.float64), projector.center.astype(np.float64))
        spans = batches(len(points))
        list(pool().map(lambda span: kernels.ray_angles(points, *centres, out, *span), spans))
        return out
    for part in point_blocks(len(points)):  # a block at a time: no (N, 3) temporaries
        p = points[part].astype(np.float32)
        cos = np.einsum("ij,ij->i", _ray_directions(camera, p), _ray_directions(projector, p))
        out[part] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def expected_error_mm(cloud: PointSet, camera: CameraModel, projector: CameraModel, coded: str = "both") -> np.ndarray:
    """Expected error along the surface normal of each point of one pair (mm, up to a common scale).

    One projector pixel of decoding noise (more where the decode quality is lower) moves the
    projector's light by distance / f at the point. A codec of columns only (`coded="u"`) fixes a
    plane through the projector: the point slides along the camera ray by that shift over the sine of
    the ray's angle to the plane. Codecs of both coordinates fix the projector ray: the sine of the
    angle between the two rays. Of the slide, the part along the surface normal counts."""
    points = cloud.points
    cam_rays = _ray_directions(camera, points)
    if coded in ("u", "v"):
        axis = 0 if coded == "u" else 1
        if projector.projection == "orthographic":
            local = np.zeros((len(points), 3))
            local[:, axis] = 1.0
        else:
            device = projector.to_device(points)
            local = np.zeros((len(points), 3))
            local[:, axis] = 1.0
            local[:, 2] = -device[:, axis] / device[:, 2]  # plane through the centre and this column
        plane_normals = local @ projector.R  # device -> world
        plane_normals /= np.linalg.norm(plane_normals, axis=1, keepdims=True)
        sin = np.abs(np.einsum("ij,ij->i", cam_rays, plane_normals))
    else:
        proj_rays = _ray_directions(projector, points)
        sin = np.sqrt(np.clip(1.0 - np.einsum("ij,ij->i", cam_rays, proj_rays) ** 2, 0.0, 1.0))
    focal = projector.K[1, 1] if coded == "v" else projector.K[0, 0]
    if projector.projection == "orthographic":
        pixel_mm = np.full(len(points), 1.0 / focal)
    else:
        pixel_mm = np.linalg.norm(points - projector.center, axis=1) / focal
    along_normal = np.abs(np.einsum("ij,ij->i", cam_rays, cloud.normals.astype(np.float64)))
    quality = np.clip(cloud.quality.astype(np.float64), 1e-3, None)
    return pixel_mm * np.maximum(along_normal, 0.05) / (np.maximum(sin, 1e-3) * quality)


def local_noise_mm(points: np.ndarray, neighbours: int = 12, chunk: int = 100_000) -> np.ndarray:
    """Spread (mm) of each point's neighbourhood about its best-fitting plane: the noise one pair's
    samples show on a smooth surface (and more on an edge, where no plane fits)."""
    if len(points) <= neighbours:
        return np.zeros(len(points))
    tree = cKDTree(points)
    out = np.empty(len(points))
    for start in range(0, len(points), chunk):
        _, index = tree.query(points[start : start + chunk], neighbours, workers=-1)
        near = points[index]
        centred = near - near.mean(axis=1, keepdims=True)
        covariance = np.einsum("nki,nkj->nij", centred, centred) / neighbours
        out[start : start + chunk] = np.sqrt(np.maximum(np.linalg.eigvalsh(covariance)[:, 0], 0.0))
    return out


def sampling_distance(cloud: PointSet) -> dict[int, float]:
    """Median distance to the nearest point of the same pair, per pair (mm)."""
    out = {}
    for source in np.unique(cloud.source):
        points = cloud.points[cloud.source == source]
        if len(points) < 2:
            continue
        distances, _ = cKDTree(points).query(points, k=2, workers=-1)
        out[int(source)] = float(np.median(distances[:, 1]))
    return out


def compare_across_pairs(
    points: np.ndarray, source: np.ndarray, score: np.ndarray, radius: float, neighbours: int = 16, chunk: int = 200_000
) -> tuple[np.ndarray, np.ndarray]:
    """(keep, overlap) masks: a point is kept unless a point of another pair with a higher score
    (ties: the lower index) lies within `radius`; it overlaps if any point of another pair does.
    Chunked queries of the nearest `neighbours` among all other pairs' points: memory stays bounded
    by the chunk, not by how many points lie close."""
    keep, overlap = np.ones(len(points), bool), np.zeros(len(points), bool)
    for a in np.unique(source):
        mine, theirs = np.flatnonzero(source == a), np.flatnonzero(source != a)
        if len(theirs) == 0:
            continue
        tree = cKDTree(points[theirs])  # every other pair at once: one query per point
        k = min(neighbours, len(theirs))
        for start in range(0, len(mine), chunk):
            rows = mine[start : start + chunk]
            distance, found = tree.query(points[rows], k, distance_upper_bound=radius, workers=-1)
            distance, found = distance.reshape(len(rows), k), found.reshape(len(rows), k)
            near = np.isfinite(distance)
            other = theirs[np.where(near, found, 0)]
            better = near & (
                (score[other] > score[rows, None]) | ((score[other] == score[rows, None]) & (other < rows[:, None]))
            )
            overlap[rows] |= near.any(axis=1)
            keep[rows] &= ~better.any(axis=1)
    return keep, overlap


def thin(points: np.ndarray, score: np.ndarray, voxel: float) -> np.ndarray:
    """Mask keeping the best-scoring point of every voxel of edge `voxel`."""
    cells = np.floor((points - bounds(points)[0]) / voxel).astype(np.int64)
    order = np.lexsort((-score, cells[:, 2], cells[:, 1], cells[:, 0]))  # best first within a cell
    ordered = cells[order]
    first = np.ones(len(order), bool)
    first[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    keep = np.zeros(len(points), bool)
    keep[order[first]] = True
    return keep


def subset(cloud: PointSet, keep: np.ndarray) -> PointSet:
    return PointSet(*(getattr(cloud, f)[keep] for f in PointSet.FIELDS))


def merge(
    cloud: PointSet, score: np.ndarray, radius_mm: float | None = None, voxel_mm: float | None = None
) -> tuple[PointSet, np.ndarray, MergeReport]:
    """Merge a cloud of several pairs (`source`); `score` is higher for better points. The voxel
    defaults to the coarsest pair's sampling distance, the radius to twice that: a badly
    conditioned sample sits off the surface by more than the spacing and must still meet the
    better neighbour that replaces it. Returns the cloud, the indices kept (into the input) and a
    report."""
    spacing = sampling_distance(cloud)
    sampling = max(spacing.values()) if spacing else 0.0
    radius = radius_mm if radius_mm is not None else RADIUS_IN_SAMPLINGS * sampling
    voxel = voxel_mm if voxel_mm is not None else sampling
    n = len(cloud)
    index = np.arange(n)
    overlap, keep = np.zeros(n, bool), np.ones(n, bool)
    if radius > 0:
        keep, overlap = compare_across_pairs(cloud.points, cloud.source, score, radius)
    after_redundancy = int(keep.sum())
    index = index[keep]
    if voxel > 0 and len(index):
        index = index[thin(cloud.points[index], score[index], voxel)]
    merged = subset(cloud, index)
    sources = np.unique(cloud.source)
    report = MergeReport(
        points_in=n,
        redundant_removed=n - after_redundancy,
        thinned_removed=after_redundancy - len(index),
        points_out=len(index),
        sampling_mm=sampling,
        radius_mm=radius,
        voxel_mm=voxel if voxel > 0 else None,
        kept_per_pair={int(s): int((merged.source == s).sum()) for s in sources},
        overlap_per_pair={int(s): int((overlap & (cloud.source == s)).sum()) for s in sources},
    )
    return merged, index, report
