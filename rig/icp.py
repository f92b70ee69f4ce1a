"""Point-to-plane ICP: realign one pair's cloud to another's where they overlap, for rigs whose
calibration drifted (a projector-camera head knocked out of place).

Each iteration pairs every source point with its nearest target point (within `max_distance`),
then solves the small-angle linearisation of sum(((R p + t) - q) . n_q)^2 for the rotation and
translation (Chen and Medioni's point-to-plane error), until the update is below a micrometre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

MIN_CORRESPONDENCES = 200


@dataclass(frozen=True)
class Alignment:
    rotation: np.ndarray  # (3, 3), applied as R @ p + t
    translation: np.ndarray  # (3,)
    correspondences: int
    rms_before_mm: float
    rms_after_mm: float
    iterations: int

    @property
    def angle_deg(self) -> float:
        return float(np.degrees(np.linalg.norm(Rotation.from_matrix(self.rotation).as_rotvec())))

    def apply(self, points: np.ndarray) -> np.ndarray:
        return points @ self.rotation.T + self.translation

    def as_dict(self) -> dict[str, float | int]:
        return {
            "rotation_deg": round(self.angle_deg, 5),
            "translation_mm": round(float(np.linalg.norm(self.translation)), 5),
            "correspondences": self.correspondences,
            "rms_before_mm": round(self.rms_before_mm, 5),
            "rms_after_mm": round(self.rms_after_mm, 5),
            "iterations": self.iterations,
        }


def point_to_plane(
    source: np.ndarray,
    target: np.ndarray,
    target_normals: np.ndarray,
    max_distance: float,
    iterations: int = 50,
    sample: int = 30000,
    seed: int = 0,
) -> Alignment | None:
    """The rigid motion that brings `source` onto the surface sampled by `target`; None when
    fewer than MIN_CORRESPONDENCES points overlap."""
    rng = np.random.default_rng(seed)
    src = source if len(source) <= sample else source[rng.choice(len(source), sample, replace=False)]
    tree = cKDTree(target)
    rotation, translation = np.eye(3), np.zeros(3)
    rms_before = None
    n_used, rms = 0, float("nan")
    done = 0
    for done in range(1, iterations + 1):  # noqa: B007 - the count is reported
        moved = src @ rotation.T + translation
        distance, index = tree.query(moved, distance_upper_bound=max_distance)
        ok = np.isfinite(distance)
        n_used = int(ok.sum())
        if n_used < MIN_CORRESPONDENCES:
            return None
        p, q, n = moved[ok], target[index[ok]], target_normals[index[ok]].astype(np.float64)
        residual = np.einsum("ij,ij->i", q - p, n)
        rms = float(np.sqrt(np.mean(residual**2)))
        if rms_before is None:
            rms_before = rms
        a = np.hstack([np.cross(p, n), n])
        step, *_ = np.linalg.lstsq(a, residual, rcond=None)
        increment = Rotation.from_rotvec(step[:3]).as_matrix()
        rotation = increment @ rotation
        translation = increment @ translation + step[3:]
        if np.linalg.norm(step[3:]) < 1e-4 and np.linalg.norm(step[:3]) < 1e-7:
            break
    return Alignment(rotation, translation, n_used, float(rms_before or 0.0), rms, done)
