"""Moving a pair's results rigidly, and realigning the pairs of a scan to one another by ICP
before they are merged (scan.merge.refine: icp)."""

from __future__ import annotations

import dataclasses

import numpy as np

from rig.opened_rig import Rig
from rig.pipeline.icp import AlignmentRefusedError, point_to_plane
from rig.pipeline.pointset import PointSet
from rig.pipeline.results import PairResult


def moved_pair(pair: PairResult, rotation: np.ndarray, shift: np.ndarray) -> PairResult:
    """The pair's results moved rigidly by x -> rotation x + shift: grid, points, normals, rings."""

    def move(points: np.ndarray) -> np.ndarray:
        return points @ rotation.T + shift

    rings = pair.rings
    if rings is not None:
        rings = dataclasses.replace(
            rings,
            points=move(rings.points),
            other_root=move(rings.other_root),
            origins=move(rings.origins),
            directions=rings.directions @ rotation.T,
        )
    points = dataclasses.replace(
        pair.points,
        points=move(pair.points.points),
        normals=(pair.points.normals @ rotation.T).astype(np.float32),
    )
    surface = pair.surface
    if surface is not None:
        surface = dataclasses.replace(
            surface,
            vertices=move(surface.vertices),
            normals=surface.normals @ rotation.T,
            grid=move(surface.grid).astype(surface.grid.dtype),
        )
    stored = None if pair.stored_grid is None else move(pair.stored_grid)
    return dataclasses.replace(pair, stored_grid=stored, rings=rings, points=points, surface=surface)


def align_pairs(rig: Rig, pairs: list[PairResult], max_distance_mm: float) -> dict[str, object]:
    """Realign every pair to those before it (the first stays) by point-to-plane ICP, replacing
    the pairs in the list by their moved results. A pair whose overlap cannot fix the motion (too
    small, flat, symmetric) stays as calibrated and the report says why."""
    report: dict[str, object] = {}
    for k in range(1, len(pairs)):
        pair = pairs[k]
        name = f"{rig.config.projectors[pair.projector].name}/{rig.config.cameras[pair.camera].name}"
        reference = PointSet.concatenate([p.points for p in pairs[:k]])
        try:
            found = point_to_plane(
                pair.points.points, pair.points.normals, reference.points, reference.normals, max_distance_mm
            )
        except AlignmentRefusedError as exc:
            report[name] = f"left as calibrated: {exc}"
            continue
        pairs[k] = moved_pair(pair, found.rotation, found.translation)
        report[name] = found.as_dict()
    return report
