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
MIN_CONDITIONING = 1e-4  # weakest / strongest direction of the normal equations, rotations scaled to mm


class AlignmentRefusedError(Exception):
    """Raised when the overlap cannot fix a rigid motion: too few points pair up, or the surface
    they share leaves a motion free (a plane lets the cloud slide along it, a sphere turn)."""


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

    def as_dict(self) -> dict[str, float | int]:
        return {
            "rotation_deg": round(self.angle_deg, 5),
            "translation_mm": round(float(np.linalg.norm(self.translation)), 5),
            "correspondences": self.correspondences,
            "rms_before_mm": round(self.rms_before_mm, 5),
            "rms_after_mm": round(self.rms_after_mm, 5),
            "iterations": self.iterations,
        }


def _conditioning(p: np.ndarray, n: np.ndarray) -> float:
    """How well point-to-plane pairings fix all six motions: the ratio of the weakest to the
    strongest eigenvalue of the normal equations, rotations scaled by the cloud's size."""
    size = float(np.sqrt(np.mean(np.sum(p**2, axis=1)))) or 1.0
    a = np.hstack([np.cross(p, n) / size, n])
    eigen = np.linalg.eigvalsh(a.T @ a)
    return float(eigen[0] / eigen[-1]) if eigen[-1] > 0 else 0.0


def point_to_plane(
    source: np.ndarray,
    source_normals: np.ndarray,
    target: np.ndarray,
    target_normals: np.ndarray,
    max_distance: float,
    iterations: int = 50,
    sample: int = 30000,
    seed: int = 0,
) -> Alignment:
    """The rigid motion that brings `source` onto the surface sampled by `target`. Raises
    AlignmentRefusedError when the overlap cannot fix it. A pairing counts only where the two normals
    agree (within about 35 degrees) and its residual is not among the largest tenth: points where
    the clouds do not overlap find a nearest point on the other cloud's border, not their own
    surface."""
    rng = np.random.default_rng(seed)
    chosen = np.arange(len(source)) if len(source) <= sample else rng.choice(len(source), sample, replace=False)
    centre = target.mean(axis=0)  # solve about the data, not the world origin: rotations stay small
    src, src_normals = source[chosen] - centre, source_normals[chosen].astype(np.float64)
    target = target - centre
    tree = cKDTree(target)
    rotation, translation = np.eye(3), np.zeros(3)
    rms_before = None
    n_used, rms = 0, float("nan")
    done = 0
    for done in range(1, iterations + 1):
        moved = src @ rotation.T + translation
        distance, index = tree.query(moved, distance_upper_bound=max_distance)
        ok = np.isfinite(distance)
        ok[ok] &= np.einsum("ij,ij->i", src_normals[ok] @ rotation.T, target_normals[index[ok]]) > 0.8
        p, q, n = moved[ok], target[index[ok]], target_normals[index[ok]].astype(np.float64)
        residual = np.einsum("ij,ij->i", q - p, n)
        inliers = np.abs(residual) <= np.quantile(np.abs(residual), 0.9) if len(residual) else residual > 0
        p, q, n, residual = p[inliers], q[inliers], n[inliers], residual[inliers]
        n_used = len(residual)
        if n_used < MIN_CORRESPONDENCES:
            raise AlignmentRefusedError(f"only {n_used} points pair up within {max_distance:g} mm")
        if done == 1 and _conditioning(p, n) < MIN_CONDITIONING:
            raise AlignmentRefusedError("the shared surface leaves a motion free (flat, or symmetric)")
        rms = float(np.sqrt(np.mean(residual**2)))
        if rms_before is None:
            rms_before = rms
        a = np.hstack([np.cross(p, n), n])
        step, *_ = np.linalg.lstsq(a, residual, rcond=None)
        increment = Rotation.from_rotvec(step[:3]).as_matrix()
        rotation = increment @ rotation
        translation = increment @ translation + step[3:]
        if np.linalg.norm(step[3:]) < 1e-3 and np.linalg.norm(step[:3]) < 1e-6:  # a micrometre, a microradian
            break
    world_translation = translation + centre - rotation @ centre  # x -> R (x - c) + t + c
    return Alignment(rotation, world_translation, n_used, float(rms_before or 0.0), rms, done)
