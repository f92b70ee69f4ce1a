"""Triangles steep to both devices: a flank turning away, or a bridge across a depth step.

A triangle between two rings whose edge both the camera and the projector see foreshortened
(rig.kernels.triangles.triangle_tests) is either a flank of the object turning away from both (a
face's cheek toward its rim, where the rings crowd a few camera pixels apart) or a bridge from an
object's last ring to the surface behind it. Alone, a triangle cannot tell which: both are steep. Its
neighbours can. A flank continues the surface beside it, so its tilt is close to the normals its
corners take from the triangles already kept; a bridge leans across a step, far from the normals
of the surfaces on both its sides. So the steep triangles are held back, then admitted in rounds
from the kept surface outward: each round, a held triangle with two corners on the surface joins it
when its tilt lies within `max_turn_deg` of both corners' normals (of all three, once it has them).
A flank is admitted ring by ring; a bridge never is. (One corner is not enough: a bridge from a
sphere's limb to the bench continues the limb, and only its other corners, on the limb's ring too,
say it left the sphere.)
"""

from __future__ import annotations

import numpy as np

from rig.pipeline.normals import corner_sums

Faces = tuple[np.ndarray, np.ndarray, np.ndarray]  # triangles (F, 3), unit normals (F, 3), weights (F,)

MAX_ROUNDS = 64  # a flank is admitted a ring per two rounds: a face's cheek crowds about ten rings


def grown_flanks(kept: Faces, held: Faces, directions: np.ndarray, max_turn_deg: float) -> np.ndarray:
    """(F_held,) which held triangles continue the kept surface (see the module docstring); the
    samples' camera rays `directions` (M, 3) orient the normals."""
    admitted = np.zeros(len(held[0]), dtype=bool)
    least_cosine = np.cos(np.radians(max_turn_deg))
    count = len(directions)
    # the samples' normals as sums of their triangles' weighted normals (vertex_normals), grown
    # with each round's triangles
    sums = corner_sums(kept[0], kept[1] * kept[2][:, None], count)
    for _ in range(MAX_ROUNDS):
        on_surface = np.linalg.norm(sums, axis=1) > 1e-12
        touching = np.flatnonzero(~admitted & (on_surface[held[0]].sum(axis=1) >= 2))
        corners = held[0][touching]
        normals = sums[corners] / np.maximum(np.linalg.norm(sums[corners], axis=2, keepdims=True), 1e-300)
        cosine = np.einsum("ikj,ij->ik", normals, held[1][touching])
        joins = touching[np.where(on_surface[corners], cosine >= least_cosine, True).all(axis=1)]
        if len(joins) == 0:
            break
        admitted[joins] = True
        sums += corner_sums(held[0][joins], held[1][joins] * held[2][joins, None], count)
    return admitted
