"""Scene geometry for the simulated bench: procedural shapes and mesh files.

World frame: millimetres, the bench plane is z = 0 and z points up toward the devices.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from drivers.sim.texture import PlanarTexture, SolidTexture

Albedo = float | tuple[float, float, float]  # grey, or linear RGB, each in [0, 1]


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One mesh with a uniform diffuse albedo (grey or RGB) in [0, 1], or a planar texture, and a
    specular lobe of `specular` strength and `roughness` (drivers.sim.materials; 0: matte)."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    albedo: Albedo
    texture: PlanarTexture | None = None
    specular: float = 0.0
    roughness: float = 0.3


@dataclass(frozen=True, eq=False)
class Scene:
    """All objects merged into one mesh, with a per-face RGB albedo (F, 3)."""

    vertices: np.ndarray
    faces: np.ndarray
    face_albedo: np.ndarray
    objects: tuple[SceneObject, ...]
    face_object: np.ndarray  # (F,) index into objects
    texture: SolidTexture | None = None  # paints every object, in place of its albedo

    @property
    def glossy(self) -> bool:
        """Whether any object has a specular lobe."""
        return any(obj.specular > 0 for obj in self.objects)

    def face_material(self) -> tuple[np.ndarray, np.ndarray]:
        """(F,) each face's specular strength and roughness."""
        strength = np.array([obj.specular for obj in self.objects], dtype=np.float64)
        roughness = np.array([obj.roughness for obj in self.objects], dtype=np.float64)
        return strength[self.face_object], roughness[self.face_object]


MAX_MESH_FILE_BYTES = 512 << 20
MAX_MESH_FACES = 5_000_000  # the ray caster's tree and the per-face tables fit in a few GB


def build_scene(objects: list[SceneObject], texture: SolidTexture | None = None) -> Scene:
    if not objects:
        raise ValueError("a scene needs at least one object")
    vertices, faces, albedo, owner = [], [], [], []
    offset = 0
    for i, obj in enumerate(objects):
        vertices.append(obj.vertices)
        faces.append(obj.faces + offset)
        rgb = np.broadcast_to(np.asarray(obj.albedo, dtype=np.float32), (3,))
        albedo.append(np.tile(rgb, (len(obj.faces), 1)))
        owner.append(np.full(len(obj.faces), i, dtype=np.int32))
        offset += len(obj.vertices)
    return Scene(
        np.vstack(vertices), np.vstack(faces), np.concatenate(albedo), tuple(objects), np.concatenate(owner), texture
    )


def printed_plane(
    name: str, image: np.ndarray, mm_per_px: float, rotation: np.ndarray, translation: np.ndarray
) -> SceneObject:
    """A flat card printed with `image` (albedo, float in [0, 1]): its top-left corner at
    `translation`, its x and y axes (image columns and rows) and normal the columns of `rotation`."""
    h, w = image.shape
    corners = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], dtype=float) * mm_per_px
    vertices = corners @ rotation.T + translation
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    texture = PlanarTexture(image.astype(np.float32), mm_per_px, np.asarray(translation, float), rotation)
    return SceneObject(name, vertices, faces, float(image.mean()), texture)


def _object(name: str, mesh: trimesh.Trimesh, albedo: Albedo) -> SceneObject:
    return SceneObject(name, np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64), albedo)


def plane(size_mm: float = 600.0, albedo: Albedo = 0.7, height_mm: float = 0.0) -> SceneObject:
    """A square of side `size_mm` in the plane z = height_mm, facing up."""
    h = size_mm / 2
    vertices = np.array([[-h, -h, height_mm], [h, -h, height_mm], [h, h, height_mm], [-h, h, height_mm]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return SceneObject("plane", vertices, faces, albedo)


def sphere(
    radius_mm: float, center_mm: tuple[float, float, float], albedo: Albedo = 0.8, subdivisions: int = 6
) -> SceneObject:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius_mm)
    mesh.apply_translation(center_mm)
    return _object("sphere", mesh, albedo)


def box(
    extents_mm: tuple[float, float, float],
    center_mm: tuple[float, float, float],
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    albedo: Albedo = 0.8,
) -> SceneObject:
    mesh = trimesh.creation.box(extents=extents_mm)
    _pose(mesh, 1.0, center_mm, rotation_deg)
    return _object("box", mesh, albedo)


def steps(
    rises_mm: tuple[float, ...],
    run_mm: float,
    width_mm: float,
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    albedo: Albedo = 0.8,
) -> SceneObject:
    """A staircase on the plane z = 0, centred on the origin: step k is `run_mm` deep along x,
    `width_mm` wide along y, and `rises_mm[k]` higher than the one before (sharp depth edges)."""
    parts = []
    height = 0.0
    total = run_mm * len(rises_mm)
    for k, rise in enumerate(rises_mm):
        height += rise
        block = trimesh.creation.box(extents=(run_mm, width_mm, height))
        block.apply_translation((-total / 2 + (k + 0.5) * run_mm, 0.0, height / 2))
        parts.append(block)
    mesh = trimesh.util.concatenate(parts)
    _pose(mesh, 1.0, (0.0, 0.0, 0.0), rotation_deg)
    return _object("steps", mesh, albedo)


def blocks(
    count: int,
    block_mm: float,
    heights_mm: tuple[float, float],
    seed: int,
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    albedo: Albedo = 0.8,
) -> SceneObject:
    """A `count` x `count` grid of touching square blocks on the plane z = 0, centred on the origin,
    each `block_mm` wide and of a seeded height in `heights_mm`: depth edges in both directions,
    corners where three heights meet."""
    rng = np.random.default_rng(seed)
    heights = rng.uniform(heights_mm[0], heights_mm[1], (count, count))
    parts = []
    offset = -count * block_mm / 2
    for i in range(count):
        for j in range(count):
            block = trimesh.creation.box(extents=(block_mm, block_mm, heights[i, j]))
            block.apply_translation((offset + (i + 0.5) * block_mm, offset + (j + 0.5) * block_mm, heights[i, j] / 2))
            parts.append(block)
    mesh = trimesh.util.concatenate(parts)
    _pose(mesh, 1.0, (0.0, 0.0, 0.0), rotation_deg)
    return _object("blocks", mesh, albedo)


def terrain(
    size_mm: float = 400.0, amplitude_mm: float = 30.0, grid: int = 257, seed: int = 7, albedo: Albedo = 0.75
) -> SceneObject:
    """A smooth height field z = f(x, y) >= 0: a sum of seeded Gaussian hills and a gentle wave."""
    rng = np.random.default_rng(seed)
    axis = np.linspace(-size_mm / 2, size_mm / 2, grid)
    x, y = np.meshgrid(axis, axis)
    z = np.zeros_like(x)
    for _ in range(6):
        cx, cy = rng.uniform(-0.35, 0.35, 2) * size_mm
        sigma = rng.uniform(0.08, 0.18) * size_mm
        z += rng.uniform(0.3, 1.0) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sigma**2))
    z += 0.15 * np.sin(2 * np.pi * x / (0.6 * size_mm)) * np.cos(2 * np.pi * y / (0.8 * size_mm))
    z = (z - z.min()) / (z.max() - z.min()) * amplitude_mm
    vertices = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    idx = np.arange(grid * grid).reshape(grid, grid)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return SceneObject("terrain", vertices, faces, albedo)


def mesh_file(
    path: str | Path,
    scale: float = 1.0,
    position_mm: tuple[float, float, float] = (0, 0, 0),
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    albedo: Albedo = 0.8,
    fit_size_mm: float | None = None,
) -> SceneObject:
    """A PLY, OBJ or STL file, scaled about its bounding-box centre (by `scale`, or so that its
    largest extent is `fit_size_mm`), rotated (x, y, z Euler angles, degrees) and placed so that the
    centre of its base sits at `position_mm`.

    Raises FileNotFoundError for a missing file and ValueError for one that is too large, has no
    triangles, has vertices that are not finite, or only triangles of zero area (those of zero area
    among others are dropped).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"mesh file not found: {path}")
    if path.stat().st_size > MAX_MESH_FILE_BYTES:
        raise ValueError(f"mesh file {path} is over {MAX_MESH_FILE_BYTES >> 20} MiB; decimate it first")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for bad files
        raise ValueError(f"cannot read mesh file {path}: {exc}") from exc
    mesh = _usable(mesh, path)
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    if fit_size_mm is not None:
        scale = fit_size_mm / float(np.max(mesh.extents))
    _pose(mesh, scale, (0, 0, 0), rotation_deg)
    base = np.array([*mesh.bounds.mean(axis=0)[:2], mesh.bounds[0, 2]])
    mesh.apply_translation(np.asarray(position_mm, float) - base)
    return _object(path.stem, mesh, albedo)


def _usable(mesh: object, path: Path) -> trimesh.Trimesh:
    """The mesh's triangles of non-zero area, or ValueError saying why there are none to use."""
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"mesh file {path} has no triangles")
    if len(mesh.faces) > MAX_MESH_FACES:
        raise ValueError(f"mesh file {path} has {len(mesh.faces)} triangles, over {MAX_MESH_FACES}; decimate it first")
    if mesh.faces.max() >= len(mesh.vertices) or mesh.faces.min() < 0:
        raise ValueError(f"mesh file {path}: a triangle names a vertex that is not in the file")
    mesh.remove_unreferenced_vertices()  # vertices no triangle uses do no harm, whatever they hold
    bad = ~np.isfinite(mesh.vertices).all(axis=1)
    if bad.any():
        raise ValueError(f"mesh file {path}: {int(bad.sum())} vertices are not finite numbers (NaN or infinity)")
    extent = float(np.max(mesh.extents))
    if not extent < 1e12:  # its areas would overflow: no scanner's unit makes such a file
        raise ValueError(f"mesh file {path}: coordinates span {extent:g}, too large to be a mesh to scan")
    area = mesh.area_faces
    kept = area > (1e-12 * extent * extent)
    if extent <= 0 or not kept.any():
        raise ValueError(f"mesh file {path}: every triangle has zero area (its vertices coincide or lie on a line)")
    if not kept.all():
        mesh.update_faces(kept)
        mesh.remove_unreferenced_vertices()
    mesh.merge_vertices()
    return mesh


def _pose(
    mesh: trimesh.Trimesh, scale: float, center_mm: tuple[float, float, float], rotation_deg: tuple[float, float, float]
) -> None:
    mesh.apply_scale(scale)
    rx, ry, rz = np.radians(rotation_deg)
    rotation = trimesh.transformations.euler_matrix(rx, ry, rz, "sxyz")
    mesh.apply_transform(rotation)
    mesh.apply_translation(center_mm)
