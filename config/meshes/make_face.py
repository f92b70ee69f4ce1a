"""Make face.ply, a face-like relief for the ring-economy benchmark and the tests: a half ellipsoid
(the head) with a nose, brow, eye sockets, cheeks, lips and chin, about 1 unit tall, facing +z
(slrig scales mesh files to size and sets them on the bench plane). Procedural and deterministic,
so it carries no licence but slrig's. Run: python config/meshes/make_face.py"""

from pathlib import Path

import numpy as np
import trimesh

HALF_WIDTH, HALF_HEIGHT, DEPTH = 0.38, 0.5, 0.3


def bump(x: np.ndarray, y: np.ndarray, cx: float, cy: float, sx: float, sy: float, height: float) -> np.ndarray:
    return height * np.exp(-(((x - cx) / sx) ** 2) - ((y - cy) / sy) ** 2)


def relief(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height over the base plane (y up the face, x across it)."""
    inside = np.clip(1.0 - (x / HALF_WIDTH) ** 2 - (y / HALF_HEIGHT) ** 2, 0.0, None)
    head = DEPTH * np.sqrt(inside)
    features = (
        bump(x, y, 0.0, -0.02, 0.045, 0.16, 0.11)  # nose ridge
        + bump(x, y, 0.0, -0.13, 0.07, 0.05, 0.05)  # nose tip
        - bump(x, y, -0.13, 0.1, 0.08, 0.05, 0.06)  # eye sockets
        - bump(x, y, 0.13, 0.1, 0.08, 0.05, 0.06)
        + bump(x, y, 0.0, 0.19, 0.25, 0.04, 0.03)  # brow
        + bump(x, y, -0.2, -0.08, 0.09, 0.1, 0.03)  # cheeks
        + bump(x, y, 0.2, -0.08, 0.09, 0.1, 0.03)
        + bump(x, y, 0.0, -0.26, 0.1, 0.025, 0.025)  # lips
        - bump(x, y, 0.0, -0.3, 0.09, 0.012, 0.012)  # the line between them
        + bump(x, y, 0.0, -0.42, 0.1, 0.05, 0.02)  # chin
    )
    return np.where(inside > 0, head + features * np.sqrt(inside), 0.0)


def face(samples: int = 151) -> trimesh.Trimesh:
    xs = np.linspace(-HALF_WIDTH, HALF_WIDTH, samples)
    ys = np.linspace(-HALF_HEIGHT, HALF_HEIGHT, int(samples * HALF_HEIGHT / HALF_WIDTH))
    x, y = np.meshgrid(xs, ys)
    z = relief(x, y)
    vertices = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    rows, cols = x.shape
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    c, d = index[1:, :-1].ravel(), index[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    raised = (z.ravel()[faces] > 0).any(axis=1)  # the flat margin is the bench plane's job
    mesh = trimesh.Trimesh(vertices, faces[raised], process=True)
    mesh.remove_unreferenced_vertices()
    return mesh


if __name__ == "__main__":
    out = Path(__file__).with_name("face.ply")
    face().export(out, encoding="binary")
    print(out)
