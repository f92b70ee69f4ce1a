"""Binary little-endian PLY: x y z, nx ny nz (float), red green blue (uchar), quality (float),
source (uchar), angle (float, the triangulation angle in degrees): the names Open3D, MeshLab and
CloudCompare read (they keep the extra properties as scalar fields)."""

from __future__ import annotations

import numpy as np

from rig.pipeline.pointset import PointSet

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
    n = len(cloud)
    vertex = np.empty(n, dtype=_VERTEX)
    for i, axis in enumerate("xyz"):
        vertex[axis] = cloud.points[:, i]
        vertex["n" + axis] = cloud.normals[:, i]
    for i, channel in enumerate(("red", "green", "blue")):
        vertex[channel] = cloud.colors[:, i]
    vertex["quality"] = cloud.quality
    vertex["source"] = cloud.source
    vertex["angle"] = cloud.angle
    lines = ["ply", "format binary_little_endian 1.0", f"comment {comment}", f"element vertex {n}"]
    lines += [f"property {'float' if _VERTEX[name].kind == 'f' else 'uchar'} {name}" for name in _VERTEX.names]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii") + vertex.tobytes()
