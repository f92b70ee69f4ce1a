"""Compare compiled ray casters for the simulated bench; prints one JSON object.

Casts one ray per pixel of a 1280x1024 camera at a sphere-on-plane scene, the workload of the
simulator's geometry pass, with each backend that is installed (embreex direct, trimesh+embreex,
Open3D RaycastingScene).
"""

from __future__ import annotations

import json
import time

import numpy as np
import trimesh


def _scene() -> trimesh.Trimesh:
    plane = trimesh.creation.box(extents=(600.0, 600.0, 1.0))
    plane.apply_translation((0, 0, -0.5))
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=60.0)
    sphere.apply_translation((0, 0, 60.0))
    return trimesh.util.concatenate([plane, sphere])


def _rays(width: int = 1280, height: int = 1024, f: float = 1800.0) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    d = np.stack([(u - width / 2) / f, -(v - height / 2) / f, -np.ones_like(u, dtype=float)], -1)
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.tile([0.0, 0.0, 600.0], (len(d), 1))
    return o, d


def _time(fn, repeats: int = 3) -> tuple[float, float]:
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return first, best


def main() -> None:
    mesh = _scene()
    origins, dirs = _rays()
    out: dict[str, object] = {"rays": len(dirs), "triangles": len(mesh.faces)}
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        def embree_direct() -> None:
            scene = rtcore_scene.EmbreeScene()
            TriangleMesh(scene, mesh.vertices[mesh.faces].astype(np.float32))
            scene.run(origins.astype(np.float32), dirs.astype(np.float32), output=1)

        first, best = _time(embree_direct)
        out["embreex_s"] = {"first": round(first, 3), "best": round(best, 3)}
    except ImportError as exc:
        out["embreex_s"] = f"unavailable: {exc}"
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        def trimesh_embree() -> None:
            RayMeshIntersector(mesh).intersects_id(origins, dirs, multiple_hits=False, return_locations=True)

        first, best = _time(trimesh_embree)
        out["trimesh_embreex_s"] = {"first": round(first, 3), "best": round(best, 3)}
    except ImportError as exc:
        out["trimesh_embreex_s"] = f"unavailable: {exc}"
    try:
        import open3d as o3d

        def open3d_cast() -> None:
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(
                o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.faces.astype(np.uint32))
            )
            rays = o3d.core.Tensor(np.hstack([origins, dirs]).astype(np.float32))
            scene.cast_rays(rays)

        first, best = _time(open3d_cast)
        out["open3d_s"] = {"first": round(first, 3), "best": round(best, 3)}
    except Exception as exc:
        out["open3d_s"] = f"unavailable: {exc}"
    print(json.dumps(out))


if __name__ == "__main__":
    main()
