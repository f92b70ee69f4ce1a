"""Steep triangles between rings: a flank turning away joins the surface, a bridge across a step does
not (rig.pipeline.flanks)."""

from __future__ import annotations

import numpy as np
from conftest import face_normals, face_weights

from rig.pipeline.flanks import grown_flanks

CAMERA = np.array([0.0, 0.0, 500.0])


def strips(profile: list[tuple[float, float]], samples: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rings along x, one per (y, z) of `profile`, `samples` each 2 mm apart; the triangles of each
    strip between two rings (row-major), and the camera's rays to the samples."""
    x = 2.0 * np.arange(samples)
    points = np.array([(xi, y, z) for y, z in profile for xi in x])
    tri = []
    for j in range(len(profile) - 1):
        for i in range(samples - 1):
            a, b, c, d = j * samples + i, j * samples + i + 1, (j + 1) * samples + i, (j + 1) * samples + i + 1
            tri += [(a, b, c), (b, d, c)]
    directions = points - CAMERA
    return points, np.array(tri), directions / np.linalg.norm(directions, axis=1, keepdims=True)


def faces(points: np.ndarray, tri: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    corner = points[tri]
    edges = np.linalg.norm(corner[:, [1, 2, 0]] - corner, axis=2)
    return tri, face_normals(points, tri, directions), face_weights(edges)


def split(all_faces: tuple[np.ndarray, ...], held: np.ndarray) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    return tuple(f[~held] for f in all_faces), tuple(f[held] for f in all_faces)


def test_a_flank_turning_away_is_admitted_ring_by_ring() -> None:
    profile = [(5.0 * j, 0.0) for j in range(4)]
    angle = 0.0
    for _ in range(12):  # the surface turns 6 degrees more at each ring, to 72 degrees
        angle += np.radians(6.0)
        y, z = profile[-1]
        profile.append((y + 5.0 * np.cos(angle), z - 5.0 * np.sin(angle)))
    points, tri, directions = strips(profile)
    per_strip = 2 * 11
    held = np.arange(len(tri)) >= 3 * per_strip  # the flat strips kept, every turning one held
    kept, steep = split(faces(points, tri, directions), held)
    admitted = grown_flanks(kept, steep, directions, max_turn_deg=10.0)
    assert admitted.all()
    assert not grown_flanks(kept, steep, directions, max_turn_deg=3.0).any()  # each ring turns more than that


def test_a_bridge_down_a_step_is_not_admitted() -> None:
    # a tread, then 40 mm down to another tread: the strip between them is the bridge
    profile = [(5.0 * j, 0.0) for j in range(4)] + [(15.0 + 5.0 * j, -40.0) for j in range(1, 5)]
    points, tri, directions = strips(profile)
    per_strip = 2 * 11
    bridge = (np.arange(len(tri)) >= 3 * per_strip) & (np.arange(len(tri)) < 4 * per_strip)
    kept, steep = split(faces(points, tri, directions), bridge)
    assert not grown_flanks(kept, steep, directions, max_turn_deg=10.0).any()
    # with nothing kept beyond it, a bridge is still no flank: two corners on the upper tread only
    upper = np.arange(len(tri)) < 3 * per_strip
    kept, steep = split(faces(points, tri, directions), ~upper)
    assert not grown_flanks(kept, steep, directions, max_turn_deg=10.0)[:per_strip].any()
