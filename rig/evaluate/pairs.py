"""Accuracy of a simulated scan against the bench's ground truth."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from rig.evaluate.colour import colour_metrics
from rig.evaluate.distances import LOCAL_MM as _LOCAL_MM
from rig.evaluate.distances import pixel_distances, root_mean_square
from rig.evaluate.ring_recovery import ring_coverage_on_bench
from rig.evaluate.surface import surface_metrics
from rig.geometry import CameraModel
from rig.opened_rig import GroundTruth, PixelTruth, Rig
from rig.pipeline import PairResult, moved_pair
from rig.workers import point_blocks

COMPLETE_WITHIN_MM = 1.0


def ring_distances(pair: PairResult, source: GroundTruth, truth: PixelTruth) -> np.ndarray:
    """Distance (mm) of each kept ring point to the true surface along its own (sub-pixel) ray."""
    assert pair.rings is not None
    keep = pair.rings.kept
    rec = pair.rings.points[keep]
    true, normal = source.cast(pair.rings.origins[keep], pair.rings.directions[keep])
    offset = rec - true
    local = np.isfinite(true).all(axis=1) & (np.linalg.norm(np.nan_to_num(offset, nan=np.inf), axis=1) <= _LOCAL_MM)
    dist = np.empty(len(rec))
    dist[local] = np.abs(np.einsum("ij,ij->i", offset[local], normal[local]))
    if (~local).any():
        dist[~local] = truth.nearest_distance(rec[~local])
    return dist


def point_distances(pair: PairResult, truth: PixelTruth, source: GroundTruth | None = None) -> np.ndarray:
    """Distance (mm) of each of the pair's points to the true surface, in PointSet order."""
    if pair.rings is not None:
        if source is None:
            raise ValueError("measuring ring points needs the ground truth's ray casts")
        return ring_distances(pair, source, truth)
    return pixel_distances(pair.points.points, pair.points.pixel, truth)


def ray_errors(
    pair: PairResult, truth: PixelTruth, source: GroundTruth | None = None
) -> Iterator[tuple[slice, np.ndarray]]:
    """Distance (mm) of each of the pair's points from where its own camera ray (the pixel's
    centre; a ring sample's sub-pixel position) first meets the true surface: the error along the
    ray, NaN where the ray meets no surface. A block of points at a time, in PointSet order: the
    block and its distances (float64), no array of the cloud's length."""
    if pair.rings is not None:
        if source is None:
            raise ValueError("measuring ring points needs the ground truth's ray casts")
        keep = pair.rings.kept
        true, _ = source.cast(pair.rings.origins[keep], pair.rings.directions[keep])
        yield slice(0, len(true)), np.linalg.norm(pair.rings.points[keep] - true, axis=1)
        return
    points, pixel = pair.points.points, pair.points.pixel
    true_points = truth.points.reshape(-1, 3)
    for part in point_blocks(len(pixel)):
        yield part, np.linalg.norm(points[part] - true_points[pixel[part]], axis=1)


def evaluate_pair(
    pair: PairResult, truth: PixelTruth, source: GroundTruth | None = None, dist: np.ndarray | None = None
) -> dict[str, float | int | None]:
    """rms/mean/p95 distance to the true surface (point_distances), the same figures along each
    point's own camera ray (ray_errors; they differ where a grazing surface or a depth edge puts a
    point near one surface while its ray meets another), and completeness: the fraction of camera
    pixels that see a lit, unshadowed true surface and got a point within 1 mm of it. Ring points are
    measured on their sub-pixel rays, which needs the truth's `source` (its ray casts), and add ring
    coverage (rig.evaluate.ring_recovery). `dist`: the distances of the pair's points, when already measured."""
    if dist is None:
        dist = point_distances(pair, truth, source)
    target, covered = covered_pixels(pair, truth, dist)
    n = max(1, len(dist))
    empty = len(dist) == 0  # no points: no distances (None, which JSON can carry; NaN it cannot)
    metrics = {
        "points": len(dist),
        "rms_mm": None if empty else root_mean_square(dist),
        "mean_abs_mm": None if empty else float(np.mean(dist, dtype=np.float64)),
        "p95_mm": None if empty else float(np.percentile(np.copy(dist), 95, overwrite_input=True)),
        "max_mm": None if empty else float(np.max(dist)),
        "over_1mm_fraction": float((dist > 1.0).sum() / n),
        "outliers_over_5mm": int((dist > 5.0).sum()),
        "outlier_fraction": float((dist > 5.0).sum() / n),
        "completeness": float(covered.sum() / max(1, target.sum())),
        "target_pixels": int(target.sum()),
    }
    squares, over_1mm, over_5mm = 0.0, 0, 0
    for part, along in ray_errors(pair, truth, source):
        np.copyto(along, dist[part], where=~np.isfinite(along))  # a ray that meets nothing: its surface distance
        over_1mm, over_5mm = over_1mm + int((along > 1.0).sum()), over_5mm + int((along > 5.0).sum())
        squares += float(np.dot(along, along))
    metrics["ray_rms_mm"] = None if empty else float(np.sqrt(squares / n))
    metrics.update({"ray_over_1mm_fraction": over_1mm / n, "ray_outliers_over_5mm": over_5mm})
    if pair.rings is not None:
        metrics.update(ring_coverage_on_bench(pair, truth, dist))
    if pair.surface is not None:
        metrics.update(surface_metrics(pair, truth))
        metrics.update(colour_metrics(pair, truth))
    return metrics


def covered_pixels(pair: PairResult, truth: PixelTruth, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) the camera pixels that see a lit, unshadowed true surface, and those of them with a
    point within COMPLETE_WITHIN_MM of it (`dist`: the pair's points' distances, point_distances)."""
    target = truth.hit & truth.lit
    good = np.zeros(target.size, dtype=bool)
    for part in point_blocks(len(dist)):  # a block at a time: no gather of every close point's pixel
        good[pair.points.pixel[part][dist[part] <= COMPLETE_WITHIN_MM]] = True
    return target, good.reshape(target.shape) & target


def coverage_on_bench(rig: Rig, pair: PairResult, errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """covered_pixels of one pair of a simulated scan, its `errors` as point_errors measured them."""
    return covered_pixels(pair, _truth(rig).ground_truth(pair.camera, pair.projector), errors)


def in_truth_frame(pair: PairResult, estimated: CameraModel, truth: CameraModel) -> PairResult:
    """The pair's points moved from the world frame of an estimated calibration to the true world
    frame through the camera (the estimated camera frame taken as the true one). What remains of
    the error is the shape the calibration gives, not where its world frame landed."""
    if estimated is truth:
        return pair
    rotation = truth.R.T @ estimated.R
    return moved_pair(pair, rotation, truth.R.T @ (estimated.t - truth.t))


def point_errors(rig: Rig, pair: PairResult) -> np.ndarray:
    """Distance (mm) of each of the pair's points to the true surface, in the true world frame."""
    truth = _truth(rig)
    aligned = in_truth_frame(pair, rig.camera_models[pair.camera], truth.cameras[pair.camera])
    return point_distances(aligned, truth.ground_truth(pair.camera, pair.projector), truth)


def evaluate_on_bench(rig: Rig, pair: PairResult, errors: np.ndarray | None = None) -> dict[str, float | int | None]:
    """Accuracy of one pair of a simulated scan, in the true world frame (through the camera when
    reconstruction used an estimated calibration). `errors`: point_errors, when already measured."""
    truth = _truth(rig)
    aligned = in_truth_frame(pair, rig.camera_models[pair.camera], truth.cameras[pair.camera])
    return evaluate_pair(aligned, truth.ground_truth(pair.camera, pair.projector), truth, errors)


def _truth(rig: Rig) -> GroundTruth:
    if rig.truth is None:
        raise ValueError("accuracy needs a rig with ground truth (the simulated bench)")
    return rig.truth
