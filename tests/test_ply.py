"""Binary PLY files (rig.store.ply) written a block at a time."""

from __future__ import annotations

import numpy as np

from rig.pipeline import Mesh
from rig.store.ply import mesh_ply_chunks, read_mesh_ply
from rig.workers import BLOCK_POINTS


def test_a_mesh_written_a_block_at_a_time_reads_back_whole() -> None:
    """mesh.ply is written in blocks (mesh_ply_chunks): vertices and faces across several blocks
    read back as they were."""
    rng = np.random.default_rng(2)
    count = BLOCK_POINTS + 7  # and its faces twice as many: both cross a block's end
    mesh = Mesh(
        rng.normal(size=(count, 3)).astype(np.float32),
        rng.integers(0, 256, (count, 3), dtype=np.uint8),
        rng.integers(0, count, (2 * count, 3)).astype(np.int32),
        np.arange(count),
    )
    vertices, colours, faces = read_mesh_ply(b"".join(mesh_ply_chunks(mesh)))
    assert np.array_equal(vertices, mesh.vertices) and np.array_equal(colours, mesh.colors)
    assert np.array_equal(faces, mesh.faces)
