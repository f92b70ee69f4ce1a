"""Binary little-endian PLY. Clouds: x y z, nx ny nz (float), red green blue (uchar), quality (float),
source (uchar), angle (float, the triangulation angle in degrees): the names Open3D, MeshLab and
CloudCompare read (they keep the extra properties as scalar fields)."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from rig.errors import StoreError
from rig.pipeline import Mesh, PointSet
from rig.workers import BLOCK_POINTS, point_blocks

_VERTEX = np.dtype(
    [
        ("x", "<f4"),
        ("y", "<f4"),
        ("z", "<f4"),
        ("nx", "<f4"),
        ("ny", "<f4"),
        ("nz", "<f4"),
        ("red", "u1"),
        ("green", "u1"),
        ("blue", "u1"),
        ("quality", "<f4"),
        ("source", "u1"),
        ("angle", "<f4"),
    ]
)


def ply_bytes(cloud: PointSet, comment: str = "slrig") -> bytes:
    return b"".join(ply_chunks(cloud, comment))


def ply_chunks(cloud: PointSet, comment: str = "slrig") -> Iterator[bytes]:
    """The binary PLY of `cloud` in pieces: its header, then a block of vertices at a time (2 MB)
    (written to a file one by one, a large cloud never has a second copy in memory)."""
    n = len(cloud)
    lines = ["ply", "format binary_little_endian 1.0", f"comment {comment}", f"element vertex {n}"]
    lines += [f"property {'float' if _VERTEX[name].kind == 'f' else 'uchar'} {name}" for name in _VERTEX.names]
    lines.append("end_header")
    yield ("\n".join(lines) + "\n").encode("ascii")

    def vertices(out: np.ndarray, part: slice) -> None:
        for i, axis in enumerate("xyz"):
            out[axis] = cloud.points[part, i]
            out["n" + axis] = cloud.normals[part, i]
        for i, channel in enumerate(("red", "green", "blue")):
            out[channel] = cloud.colors[part, i]
        out["quality"] = cloud.quality[part]
        out["source"] = cloud.source[part]
        out["angle"] = cloud.angle[part]

    yield from _record_blocks(_VERTEX, n, vertices)


def _record_blocks(dtype: np.dtype, count: int, fill: Callable[[np.ndarray, slice], None]) -> Iterator[bytes]:
    """The bytes of `count` records of `dtype`, a block at a time: `fill(out, part)` writes the
    records of items `part` into `out`, one block's buffer used again for every block."""
    records = np.empty(min(count, BLOCK_POINTS), dtype=dtype)
    for part in point_blocks(count):
        out = records[: part.stop - part.start]
        fill(out, part)
        yield out.tobytes()


_MESH_VERTEX = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")])
_FACE = np.dtype([("count", "u1"), ("vertex_indices", "<i4", (3,))])


def mesh_ply_bytes(mesh: Mesh, comment: str = "slrig") -> bytes:
    """mesh_ply_chunks joined: the whole file's bytes."""
    return b"".join(mesh_ply_chunks(mesh, comment))


def mesh_ply_chunks(mesh: Mesh, comment: str = "slrig") -> Iterator[bytes]:
    """Binary PLY of a triangle mesh in pieces, as ply_chunks writes a cloud (a block at a time, no
    second copy of it: whole, its records and their bytes were some 30 MB of a ring scan's peak):
    vertices x y z with red green blue, faces as lists of three vertex indices (`property list uchar
    int vertex_indices`, what Open3D and MeshLab read)."""
    vertices, faces = len(mesh.vertices), len(mesh.faces)
    lines = ["ply", "format binary_little_endian 1.0", f"comment {comment}", f"element vertex {vertices}"]
    lines += [f"property float {a}" for a in "xyz"] + [f"property uchar {c}" for c in ("red", "green", "blue")]
    lines += [f"element face {faces}", "property list uchar int vertex_indices", "end_header"]
    yield ("\n".join(lines) + "\n").encode("ascii")

    def vertex(out: np.ndarray, part: slice) -> None:
        for i, axis in enumerate("xyz"):
            out[axis] = mesh.vertices[part, i]
        for i, channel in enumerate(("red", "green", "blue")):
            out[channel] = mesh.colors[part, i]

    def face(out: np.ndarray, part: slice) -> None:
        out["count"] = 3
        out["vertex_indices"] = mesh.faces[part]

    yield from _record_blocks(_MESH_VERTEX, vertices, vertex)
    yield from _record_blocks(_FACE, faces, face)


def read_cloud_ply(data: bytes, source: str = "cloud.ply") -> PointSet:
    """A cloud written by `ply_bytes`; raises StoreError for any other layout."""
    vertex = _read_vertices(data, source, _VERTEX, "a cloud")
    count = len(vertex)
    return PointSet(
        points=np.column_stack([vertex[a] for a in "xyz"]).astype(np.float64),
        normals=np.column_stack([vertex["n" + a] for a in "xyz"]).astype(np.float32),
        colors=np.column_stack([vertex[c] for c in ("red", "green", "blue")]),
        quality=vertex["quality"].copy(),
        source=vertex["source"].copy(),
        pixel=np.full(count, -1, np.int64),
        angle=vertex["angle"].copy(),
    )


def read_mesh_vertices(data: bytes, source: str = "mesh.ply") -> np.ndarray:
    """(V, 3) float64 vertices of a mesh written by `mesh_ply_bytes`; raises StoreError for any other layout."""
    vertex = _read_vertices(data, source, _MESH_VERTEX, "a mesh")
    return np.column_stack([vertex[a] for a in "xyz"]).astype(np.float64)


def read_mesh_ply(data: bytes, source: str = "mesh.ply") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (V, 3) float32, colours (V, 3) uint8 and triangles (F, 3) int32 of a mesh written
    by `mesh_ply_bytes`; StoreError for any other layout or an index out of range."""
    vertex = _read_vertices(data, source, _MESH_VERTEX, "a mesh")
    header = data[: data.find(b"end_header\n")].decode("ascii", errors="replace").splitlines()
    faces = next((int(line.split()[2]) for line in header if line.startswith("element face ")), 0)
    start = data.find(b"end_header\n") + len(b"end_header\n") + vertex.nbytes
    if len(data) < start + faces * _FACE.itemsize:
        raise StoreError(f"{source}: truncated ({faces} faces)")
    face = np.frombuffer(data, dtype=_FACE, count=faces, offset=start)
    if faces and (
        (face["count"] != 3).any() or face["vertex_indices"].min() < 0 or face["vertex_indices"].max() >= len(vertex)
    ):
        raise StoreError(f"{source}: faces are not triangles of its vertices")
    points = np.column_stack([vertex[a] for a in "xyz"]).astype(np.float32)
    colors = np.column_stack([vertex[c] for c in ("red", "green", "blue")])
    return points, colors, face["vertex_indices"].astype(np.int32)


def _read_vertices(data: bytes, source: str, dtype: np.dtype, what: str) -> np.ndarray:
    """The vertex element of a binary PLY whose vertex properties are exactly `dtype`'s."""
    end = data.find(b"end_header\n")
    header = data[:end].decode("ascii", errors="replace").splitlines() if end >= 0 else []
    expected = [f"property {'float' if dtype[n].kind == 'f' else 'uchar'} {n}" for n in dtype.names or ()]
    count = next((int(line.split()[2]) for line in header if line.startswith("element vertex ")), None)
    body = data[end + len(b"end_header\n") :] if end >= 0 else b""
    properties = [line for line in header if line.startswith("property")]
    if count is None or properties[: len(expected)] != expected or "format binary_little_endian 1.0" not in header:
        raise StoreError(f"{source}: not {what} slrig wrote (binary PLY with {', '.join(dtype.names or ())})")
    if len(body) < count * dtype.itemsize:
        raise StoreError(f"{source}: truncated ({len(body)} bytes for {count} vertices)")
    return np.frombuffer(body, dtype=dtype, count=count)
