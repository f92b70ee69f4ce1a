"""Synthetic faces for recognition: the MeshMonk face template (shipped in the MIT `autofacemonker`
wheel, read as a PLY file, never imported), deformed into identities and expressions and posed,
reproducibly from a seed (reference 13.3-13.5).

- identity: anisotropic scale (width, height, depth), a longer or shorter nose and bridge, and a
  low-frequency relief of random Gaussian bumps along the normals;
- expression: smooth displacements anchored at landmarks, weighted by geodesic distance on the
  template (so that the lips do not move the nose): smile, surprise, frown, puffed cheeks;
- pose: a rigid rotation and shift.

The template is an open face mask facing +z (x across, y up), in units of about 65 mm.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial.transform import Rotation

MM_PER_UNIT = 65.0
INSTALL_HINT = "pip install --no-deps autofacemonker==0.2.0"
# MeshMonk template vertices of MediaPipe landmarks (autofacemonker's correspondences)
LANDMARKS = {
    "upper_lip": 3572,
    "nose_tip": 3589,
    "left_inner_eye": 2436,
    "right_inner_eye": 4648,
    "left_mouth": 2310,
    "right_mouth": 4849,
    "chin": 3543,
}
EXPRESSIONS = ("neutral", "smile", "surprise", "frown", "puff")


class FaceTemplateMissingError(FileNotFoundError):
    """Raised when the face template is not installed (its package, autofacemonker, is optional)."""


@dataclass(frozen=True, eq=False)
class Face:
    """One synthetic face: a mesh in millimetres and what it is."""

    vertices: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3)
    identity: int  # -1: the template itself
    expression: str

    def mesh(self) -> trimesh.Trimesh:
        return trimesh.Trimesh(self.vertices, self.faces, process=False)

    def write_ply(self, path: Path) -> Path:
        path.write_bytes(trimesh.exchange.ply.export_ply(self.mesh(), encoding="binary"))
        return path


def template_path() -> Path:
    """The template's PLY file inside the installed autofacemonker package."""
    spec = importlib.util.find_spec("autofacemonker")  # locates the package without importing it
    if spec is None or not spec.submodule_search_locations:
        raise FaceTemplateMissingError(f"the face template is not installed: {INSTALL_HINT}")
    path = Path(next(iter(spec.submodule_search_locations))) / "data" / "template.ply"
    if not path.is_file():
        raise FaceTemplateMissingError(f"the face template is missing from the autofacemonker package: {path}")
    return path


@cache
def template() -> Face:
    """The neutral template in millimetres, its nose tip at the origin."""
    mesh = trimesh.load(template_path(), process=False, force="mesh")
    vertices = np.asarray(mesh.vertices, float) * MM_PER_UNIT
    vertices -= vertices[LANDMARKS["nose_tip"]]
    return Face(vertices, np.asarray(mesh.faces, np.int64), -1, "neutral")


def identity(seed: int) -> Face:
    """Identity `seed`: the template reshaped, neutral."""
    base = template()
    rng = np.random.default_rng([seed, 14])
    scale = 1.0 + rng.uniform(-0.08, 0.08, 3) * np.array([1.0, 1.0, 0.75])
    vertices = base.vertices * scale
    normals = _normals(base)
    distance = _geodesic_from(base, [LANDMARKS["nose_tip"]])[0]
    nose = rng.uniform(-3.0, 3.0) * np.exp(-(distance**2) / (2 * 12.0**2))  # a longer or flatter nose
    bridge_at = _nearest(base, base.vertices[LANDMARKS["nose_tip"]] + np.array([0.0, 25.0, 0.0]))
    bridge = rng.uniform(-2.5, 2.5) * np.exp(-(_geodesic_from(base, [bridge_at])[0] ** 2) / (2 * 10.0**2))
    relief = np.zeros(len(vertices))
    centres = rng.choice(len(vertices), size=15, replace=False)
    for along in _geodesic_from(base, list(centres)):
        sigma = rng.uniform(30.0, 40.0) / 2.0  # correlation length 30-40 mm
        relief += rng.uniform(2.0, 4.0) * rng.choice([-1.0, 1.0]) * np.exp(-(along**2) / (2 * sigma**2)) / 2.0
    vertices = vertices + (nose + bridge + relief)[:, None] * normals
    return Face(vertices, base.faces, seed, "neutral")


def expression(face: Face, kind: str, strength: float = 1.0) -> Face:
    """`face` with expression `kind` (EXPRESSIONS) at `strength` (1: a clear one)."""
    if kind not in EXPRESSIONS:
        raise ValueError(f"unknown expression {kind!r}; known: {', '.join(EXPRESSIONS)}")
    base = template()
    moves: list[tuple[int, np.ndarray, float]] = []  # anchor vertex, displacement (mm), sigma (mm)
    v = base.vertices
    if kind == "smile":
        moves += [(LANDMARKS["left_mouth"], np.array([-2.5, 3.5, 0.0]), 16.0)]
        moves += [(LANDMARKS["right_mouth"], np.array([2.5, 3.5, 0.0]), 16.0)]
    elif kind == "surprise":
        for eye in ("left_inner_eye", "right_inner_eye"):
            moves.append((_brow(eye), np.array([0.0, 5.0, 0.0]), 18.0))
        moves.append((LANDMARKS["chin"], np.array([0.0, -4.0, 0.0]), 20.0))
    elif kind == "frown":
        for eye in ("left_inner_eye", "right_inner_eye"):
            brow = _brow(eye)  # down and toward the middle
            moves.append((brow, np.array([-2.0 * np.sign(v[brow, 0]), -3.0, 0.0]), 15.0))
    elif kind == "puff":
        normals = _normals(base)
        for eye, mouth in (("left_inner_eye", "left_mouth"), ("right_inner_eye", "right_mouth")):
            cheek = _cheek(eye, mouth)
            moves.append((cheek, 3.0 * normals[cheek], 18.0))
    vertices = face.vertices.copy()
    if moves:
        distances = _geodesic_from(base, [anchor for anchor, _, _ in moves])
        for (_, shift, sigma), along in zip(moves, distances, strict=True):
            vertices += strength * np.exp(-(along**2) / (2 * sigma**2))[:, None] * shift
    return Face(vertices, face.faces, face.identity, kind)


def posed(face: Face, rotation_deg: tuple[float, float, float], shift_mm: tuple[float, float, float]) -> Face:
    """`face` rotated about its nose tip by extrinsic x, y, z angles (degrees) and shifted."""
    tip = face.vertices[LANDMARKS["nose_tip"]]
    turn = Rotation.from_euler("xyz", rotation_deg, degrees=True).as_matrix()
    vertices = (face.vertices - tip) @ turn.T + tip + np.asarray(shift_mm)
    return Face(vertices, face.faces, face.identity, face.expression)


def face_set(identities: int = 10, expressions: tuple[str, ...] = EXPRESSIONS) -> list[Face]:
    """Every identity 0 .. identities-1 with every expression."""
    return [expression(identity(i), kind) for i in range(identities) for kind in expressions]


def _normals(face: Face) -> np.ndarray:
    return np.asarray(face.mesh().vertex_normals, float)


def _nearest(face: Face, point: np.ndarray) -> int:
    """The vertex nearest `point` in the image plane (x, y): a point on the face's front."""
    return int(np.argmin(np.linalg.norm(face.vertices[:, :2] - point[:2], axis=1)))


def _brow(eye: str) -> int:
    """The vertex 22 mm above and 12 mm outside an inner eye corner."""
    base = template()
    corner = base.vertices[LANDMARKS[eye]]
    return _nearest(base, corner + np.array([12.0 * np.sign(corner[0]), 22.0, 0.0]))


def _cheek(eye: str, mouth: str) -> int:
    """The vertex 20 mm outside the midpoint of an inner eye corner and a mouth corner."""
    base = template()
    middle = 0.5 * (base.vertices[LANDMARKS[eye]] + base.vertices[LANDMARKS[mouth]])
    return _nearest(base, middle + np.array([20.0 * np.sign(middle[0]), 0.0, 0.0]))


def _geodesic_from(face: Face, sources: list[int]) -> np.ndarray:
    """(S, V) shortest distances along the mesh's edges from each source vertex (weights only: an
    edge path is a few per cent longer than the surface's geodesic)."""
    edges = face.mesh().edges_unique
    length = np.linalg.norm(face.vertices[edges[:, 0]] - face.vertices[edges[:, 1]], axis=1)
    n = len(face.vertices)
    graph = coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    return np.atleast_2d(dijkstra(graph, directed=False, indices=sources))
