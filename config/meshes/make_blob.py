"""Make blob.ply, the sample mesh of the README and the tests: a lumpy, seeded, closed surface
about 1 unit across (slrig scales mesh files to size). Run: python config/meshes/make_blob.py"""

from pathlib import Path

import numpy as np
import trimesh


def blob() -> trimesh.Trimesh:
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=0.5)
    v = mesh.vertices
    direction = v / np.linalg.norm(v, axis=1, keepdims=True)
    rng = np.random.default_rng(2012)
    bump = np.zeros(len(v))
    for _ in range(9):
        center = rng.normal(size=3)
        center /= np.linalg.norm(center)
        width = rng.uniform(0.25, 0.6)
        bump += rng.uniform(-0.12, 0.2) * np.exp(-np.sum((direction - center) ** 2, axis=1) / width**2)
    mesh.vertices = direction * (0.5 + bump)[:, None] * np.array([1.0, 0.8, 0.7])
    return mesh


if __name__ == "__main__":
    out = Path(__file__).with_name("blob.ply")
    blob().export(out, encoding="binary")
    print(out)
