"""Vectorised triangulation: ray-plane and ray-ray."""

from __future__ import annotations

import numpy as np


def ray_plane(
    origins: np.ndarray,
    directions: np.ndarray,
    normals: np.ndarray,
    offsets: np.ndarray,
    min_cos: float = 1e-3,
) -> tuple[np.ndarray, np.ndarray]:
    """Intersect rays o + s d with planes n . X = c, element by element.

    Returns the points (N, 3) and a validity mask: False where the ray is nearly parallel to the
    plane (|n . d| < min_cos * |n|) or the intersection lies behind the ray origin.
    """
    denom = np.einsum("ij,ij->i", normals, directions)
    scale = np.linalg.norm(normals, axis=1)
    valid = np.abs(denom) >= min_cos * scale
    safe = np.where(valid, denom, 1.0)
    s = (offsets - np.einsum("ij,ij->i", normals, origins)) / safe
    valid &= s > 0
    return origins + s[:, None] * directions, valid


def _closest_approach(
    o1: np.ndarray, d1: np.ndarray, o2: np.ndarray, d2: np.ndarray, min_sin: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray parameters s1, s2 of the closest approach of ray pairs (unit directions), and validity:
    False for nearly parallel rays or points behind either origin."""
    w = o1 - o2
    b = np.einsum("ij,ij->i", d1, d2)
    d = np.einsum("ij,ij->i", d1, w)
    e = np.einsum("ij,ij->i", d2, w)
    denom = 1.0 - b * b
    valid = denom >= min_sin * min_sin
    safe = np.where(valid, denom, 1.0)
    s1 = (b * e - d) / safe
    s2 = (e - b * d) / safe
    valid &= (s1 > 0) & (s2 > 0)
    return s1, s2, valid


def ray_ray_midpoint(
    o1: np.ndarray, d1: np.ndarray, o2: np.ndarray, d2: np.ndarray, min_sin: float = 1e-3
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest-approach midpoint of ray pairs (unit directions).

    Returns the points (N, 3), the gap between the rays at closest approach (N,), and a validity
    mask: False for nearly parallel rays or points behind either origin.
    """
    s1, s2, valid = _closest_approach(o1, d1, o2, d2, min_sin)
    p1 = o1 + s1[:, None] * d1
    p2 = o2 + s2[:, None] * d2
    return 0.5 * (p1 + p2), np.linalg.norm(p1 - p2, axis=1), valid


def closest_on_first_ray(
    o1: np.ndarray, d1: np.ndarray, o2: np.ndarray, d2: np.ndarray, min_sin: float = 1e-3
) -> tuple[np.ndarray, np.ndarray]:
    """The point of ray 1 closest to ray 2 (unit directions), and a validity mask.

    For a camera (ray 1) and a decoded projector point (ray 2) this is the better estimate than the
    midpoint: the camera pixel is exact, the decoded projector coordinate carries the noise.
    """
    s1, _, valid = _closest_approach(o1, d1, o2, d2, min_sin)
    return o1 + s1[:, None] * d1, valid
