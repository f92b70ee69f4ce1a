"""First-hit ray casting through Embree's BVH (embreex), refined to float64.

Embree works in float32; the hit triangle it finds is re-intersected in float64
(Moller-Trumbore), so ground-truth points are exact to double precision.
bench/raycast_backends.py measured the candidates: embreex 0.30 s, Open3D 0.15 s, trimesh's
embreex wrapper 0.54 s for 1.3 M rays; Open3D needs a 105 MB wheel, a system libusb and a large
dependency tree, Embree a self-contained 15 MB wheel, and casting happens once per pose.
"""

from __future__ import annotations

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

_CHUNK = 1 << 18  # rays per call: bounds the temporaries (about 100 bytes a ray)


class RayCaster:
    """Casts rays against one triangle mesh (vertices (V, 3), faces (F, 3))."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        self._triangles = self.vertices[self.faces]
        normals = np.cross(self._triangles[:, 1] - self._triangles[:, 0], self._triangles[:, 2] - self._triangles[:, 0])
        self._face_normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, self._triangles.astype(np.float32))

    def first_hit(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance along each (unit) ray to the first hit and the face hit; inf and -1 on a miss."""
        n = len(origins)
        faces = np.full(n, -1, dtype=np.int64)
        for start in range(0, n, _CHUNK):
            stop = min(n, start + _CHUNK)
            result = self._scene.run(
                origins[start:stop].astype(np.float32),
                directions[start:stop].astype(np.float32),
                output=1,
            )
            faces[start:stop] = result["primID"]
        faces[faces < 0] = -1
        distance = np.full(n, np.inf)
        hit = np.flatnonzero(faces >= 0)
        for start in range(0, len(hit), _CHUNK):
            part = hit[start : start + _CHUNK]
            distance[part] = self._exact_distance(origins[part], directions[part], faces[part])
        return distance, faces

    def _exact_distance(self, origins: np.ndarray, directions: np.ndarray, faces: np.ndarray) -> np.ndarray:
        tri = self._triangles[faces]
        e1 = tri[:, 1] - tri[:, 0]
        e2 = tri[:, 2] - tri[:, 0]
        p = np.cross(directions, e2)
        det = np.einsum("ij,ij->i", e1, p)
        s = origins - tri[:, 0]
        q = np.cross(s, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.einsum("ij,ij->i", e2, q) / det

    def face_normals(self, faces: np.ndarray) -> np.ndarray:
        """Unit geometric normals (right-hand winding) of the given faces."""
        return self._face_normals[faces]
