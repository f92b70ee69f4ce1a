"""Accuracy of a merged multi-pair scan against the simulated bench's ground truth: error and
completeness of the merged cloud and of each pair over the object's visible surface, redundancy
left across pairs, and the intensity cue's overlap against the truth of which projectors light
each pixel."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from rig.evaluate.distances import root_mean_square
from rig.evaluate.pairs import COMPLETE_WITHIN_MM, evaluate_on_bench, point_errors
from rig.kernels import cell_keys
from rig.opened_rig import Rig
from rig.pipeline import PointSet, ScanResult, precision_recall, sampling_distance

SURFACE_SPACING_MM = 1.0


def visible_surface(rig: Rig, spacing_mm: float = SURFACE_SPACING_MM) -> np.ndarray:
    """Samples, one per `spacing_mm` cell, of the true surface that some camera sees and some
    projector lights: what the rig can measure at best."""
    source = rig.truth
    assert source is not None
    found = []
    for c in range(len(source.cameras)):
        lit = np.zeros(source.cameras[c].height * source.cameras[c].width, bool)
        truth = None
        for p in range(len(source.projectors)):
            truth = source.ground_truth(c, p)
            lit |= (truth.hit & truth.lit).ravel()
        assert truth is not None
        found.append(truth.points.reshape(-1, 3)[lit])
    points = np.concatenate(found)
    return points[_first_in_each_cell(points, spacing_mm)]


def _first_in_each_cell(points: np.ndarray, spacing_mm: float) -> np.ndarray:
    """Index of the first point in each occupied cube of side `spacing_mm`, cells in (x, y, z)
    order, as np.unique of the cells' rows with return_index gives them, but each cell's indices
    packed with the point's own into one integer and sorted: np.unique of rows sorts them as
    records, some forty times slower on a camera's million points."""
    cells = np.floor(points / spacing_mm).astype(np.int64)
    count = len(cells)
    if count == 0:
        return np.zeros(0, np.int64)
    key, keys = cell_keys(cells)
    if keys * count >= 2.0**62:  # a scene of kilometres at a micrometre
        return np.unique(cells, axis=0, return_index=True)[1]
    packed = key * count + np.arange(count)
    packed.sort()
    cell = packed // count
    first = np.ones(count, bool)
    first[1:] = cell[1:] != cell[:-1]
    return packed[first] % count


def coverage(samples: np.ndarray, points: np.ndarray, within_mm: float = COMPLETE_WITHIN_MM) -> float:
    """Fraction of the surface samples with a point within `within_mm`."""
    if len(points) == 0 or len(samples) == 0:
        return 0.0
    distance, _ = cKDTree(points).query(samples, distance_upper_bound=within_mm)
    return float(np.isfinite(distance).mean())


def cross_pair_close_fraction(points: np.ndarray, source: np.ndarray, distance_mm: float) -> float:
    """Fraction of points with a point of another pair closer than `distance_mm`."""
    if len(points) < 2:
        return 0.0
    pairs = cKDTree(points).query_pairs(distance_mm, output_type="ndarray")
    close = np.zeros(len(points), bool)
    if len(pairs):
        cross = source[pairs[:, 0]] != source[pairs[:, 1]]
        close[pairs[cross].ravel()] = True
    return float(close.mean())


def overlap_scores(rig: Rig, result: ScanResult) -> dict[str, dict[str, float | int]]:
    """Precision and recall of the cue's overlap per camera, against the pixels the truth says
    more than one projector lights (over the pixels that see a surface)."""
    source = rig.truth
    assert source is not None
    out = {}
    for c, found in result.overlap.items():
        truths = [source.ground_truth(c, p) for p in range(len(source.projectors))]
        lit_by = np.sum([t.hit & t.lit for t in truths], axis=0)
        precision, recall = precision_recall(found, lit_by >= 2, truths[0].hit)
        out[rig.config.cameras[c].name] = {
            "precision": round(precision, 4),
            "recall": round(recall, 4),
            "overlap_pixels_true": int((lit_by >= 2).sum()),
            "overlap_pixels_found": int(found.sum()),
        }
    return out


def evaluate_merge(rig: Rig, result: ScanResult, errors: list[np.ndarray] | None = None) -> dict[str, object]:
    """The merged cloud and every pair measured on the same visible surface. `errors`: each pair's
    point_errors, when already measured."""
    if rig.truth is None or result.merged_index is None:
        raise ValueError("evaluating a merge needs a simulated scan of several pairs")
    errors = errors if errors is not None else [point_errors(rig, pair) for pair in result.pairs]
    surface = visible_surface(rig)
    pairs = {}
    for pair, err in zip(result.pairs, errors, strict=True):
        name = f"{rig.config.projectors[pair.projector].name}/{rig.config.cameras[pair.camera].name}"
        pairs[name] = _summary(err, coverage(surface, pair.points.points))
    merged_errors = np.concatenate(errors)[result.merged_index]
    for summary, pair in zip(pairs.values(), result.pairs, strict=True):
        # the merged cloud where this pair measured: compare like with like, whatever else it covers
        distance, _ = cKDTree(pair.points.points).query(result.cloud.points, distance_upper_bound=COMPLETE_WITHIN_MM)
        here = merged_errors[np.isfinite(distance)]
        summary["merged_rms_mm_here"] = round(root_mean_square(here), 5) if len(here) else None
    spacing = sampling_distance(PointSet.concatenate([p.points for p in result.pairs]))
    sampling = max(spacing.values()) if spacing else 0.0
    merged = _summary(merged_errors, coverage(surface, result.cloud.points))
    merged["cross_pair_within_half_sampling"] = round(
        cross_pair_close_fraction(result.cloud.points, result.cloud.source, sampling / 2), 5
    )
    merged["sampling_mm"] = round(sampling, 4)
    return {
        "merged": merged,
        "pairs": pairs,
        "overlap_cue": overlap_scores(rig, result),
        "surface_samples": len(surface),
    }


def _summary(err: np.ndarray, completeness: float) -> dict[str, float | int | None]:
    empty = len(err) == 0
    return {
        "points": len(err),
        "rms_mm": None if empty else round(root_mean_square(err), 5),
        "p95_mm": None if empty else round(float(np.percentile(err, 95)), 5),
        "outliers_over_5mm": int((err > 5).sum()),
        "completeness": round(completeness, 4),
    }


def metrics_on_bench(rig: Rig, result: ScanResult) -> dict[str, object]:
    """Accuracy of each pair against ground truth, keyed "projector/camera", and of the merged
    cloud when several pairs were merged (rigs with ground truth only; others: {})."""
    return measure_on_bench(rig, result)[0]


def measure_on_bench(rig: Rig, result: ScanResult) -> tuple[dict[str, object], np.ndarray | None]:
    """metrics_on_bench, and the distance (mm, float32) of each point of the scan's cloud to the
    true surface, in the cloud's order (None without ground truth)."""
    if rig.truth is None:
        return {}, None
    errors = [point_errors(rig, pair) for pair in result.pairs]  # once, for the pairs and the merge
    out: dict[str, object] = {
        f"{rig.config.projectors[pair.projector].name}/{rig.config.cameras[pair.camera].name}": evaluate_on_bench(
            rig, pair, err
        )
        for pair, err in zip(result.pairs, errors, strict=True)
    }
    if result.merged_index is not None:
        merged = evaluate_merge(rig, result, errors)
        out["merged"] = merged["merged"]
        out["merged_pairs"] = merged["pairs"]
        out["overlap_cue"] = merged["overlap_cue"]
    cloud_errors = np.concatenate(errors) if errors else np.empty(0)
    if result.merged_index is not None:
        cloud_errors = cloud_errors[result.merged_index]
    return out, cloud_errors.astype(np.float32)
