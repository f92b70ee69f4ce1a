"""A stored cloud or ring mesh for the console's 3D viewer, as one compact binary body: GET
/v1/scans/{id}/cloud.bin?budget=N (a random subset of at most N points, the same subset every
time; budget=0: every point) and GET /v1/scans/{id}/mesh.bin.

The body: a 4-byte little-endian length, a JSON header of that many bytes (spaces pad it to a
multiple of 4), then the arrays its `arrays` list names, each at its `offset` from the end of
the header (4-aligned) and of `count` x `components` values of `type`: positions float32 (mm), colours
uint8 RGB, normals int8 (x127), quality uint8 (0-255 over `quality_range`), on simulated rigs
each point's distance to the true surface (float32 mm, `error`), and for meshes the triangles
uint32. A million points at full resolution are about 20 MB instead of PLY's 39.
"""

from __future__ import annotations

import asyncio
import functools
import json
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Query, Response
from fastapi import Path as PathParam

from rig.api.models import JOB_ID_PATTERN
from rig.api.security import READING
from rig.service import JobNotFoundError, JobService, JobType
from rig.store import TRUTH_ERRORS, read_cloud_ply, read_mesh_ply

DEFAULT_BUDGET = 300_000  # points: a quick first view of any scan (about 5 MB)
MEDIA_TYPE = "application/vnd.slrig.cloud"
JobId = Annotated[str, PathParam(pattern=JOB_ID_PATTERN)]


def pack(header: dict[str, Any], arrays: list[tuple[str, np.ndarray]]) -> bytes:
    """The binary body: `header` plus an `arrays` entry per array, then the arrays, 4-aligned."""
    described, offset = [], 0
    for name, array in arrays:
        components = 1 if array.ndim == 1 else array.shape[1]
        entry = {"name": name, "type": str(array.dtype), "count": len(array), "components": components}
        described.append({**entry, "offset": offset})
        offset += array.nbytes + (-array.nbytes) % 4
    text = json.dumps({**header, "arrays": described}).encode()
    parts = [b"", text + b" " * ((-len(text)) % 4)]
    parts[0] = len(parts[1]).to_bytes(4, "little")
    for _, array in arrays:
        data = np.ascontiguousarray(array).tobytes()
        parts += [data, b"\0" * ((-len(data)) % 4)]
    return b"".join(parts)


@functools.lru_cache(maxsize=4)
def cloud_body(path: Path, stamp: float, budget: int, errors_path: Path | None = None) -> bytes:
    """`stamp`: the file's mtime, so that a changed file is read again; `errors_path`: the scan's
    distances to the true surface (simulated rigs), sent as `error` when they fit the cloud."""
    cloud = read_cloud_ply(path.read_bytes(), path.name)
    total = len(cloud)
    rows = np.arange(total)
    if 0 < budget < total:
        rows = np.sort(np.random.default_rng(0).choice(total, budget, replace=False))
    points = cloud.points[rows].astype(np.float32)
    quality = cloud.quality[rows].astype(np.float32)
    finite = quality[np.isfinite(quality)]
    low, high = (float(finite.min()), float(finite.max())) if len(finite) else (0.0, 1.0)
    scaled = np.clip((np.nan_to_num(quality, nan=low) - low) / max(high - low, 1e-12) * 255, 0, 255)
    header = {
        "kind": "cloud",
        "points": len(rows),
        "total": total,
        "budget": budget,
        "bounds": [points.min(axis=0).tolist(), points.max(axis=0).tolist()] if len(points) else None,
        "quality_range": [low, high],
    }
    arrays = [
        ("position", points),
        ("color", cloud.colors[rows].astype(np.uint8)),
        ("normal", np.clip(np.round(cloud.normals[rows] * 127), -127, 127).astype(np.int8)),
        ("quality", scaled.astype(np.uint8)),
    ]
    errors = _errors(errors_path, total)
    if errors is not None:
        arrays.append(("error", errors[rows]))
        finite = errors[np.isfinite(errors)]
        header["error_p95_mm"] = float(np.percentile(finite, 95)) if len(finite) else None
    return pack(header, arrays)


def _errors(path: Path | None, count: int) -> np.ndarray | None:
    if path is None:
        return None
    try:
        errors = np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        return None  # unreadable: the viewer goes without
    return errors.astype(np.float32) if errors.shape == (count,) else None


@functools.lru_cache(maxsize=2)
def mesh_body(path: Path, stamp: float) -> bytes:
    vertices, colors, faces = read_mesh_ply(path.read_bytes(), path.name)
    points = vertices.astype(np.float32)
    header = {
        "kind": "mesh",
        "points": len(points),
        "triangles": len(faces),
        "bounds": [points.min(axis=0).tolist(), points.max(axis=0).tolist()] if len(points) else None,
    }
    return pack(header, [("position", points), ("color", colors), ("triangles", faces.astype(np.uint32))])


def cloud_router(service: JobService, errors: dict[int | str, dict[str, Any]]) -> APIRouter:
    router = APIRouter(prefix="/scans", tags=["scans"], responses=errors)

    def stored(job_id: str, name: str) -> Path:
        job = service.job(job_id, JobType.SCAN)
        if name not in (job.result or {}).get("files", []):
            raise JobNotFoundError(f"scan {job_id} has no {name}")
        return service.file_path(job_id, JobType.SCAN, name)

    def errors_of(job_id: str) -> Path | None:
        try:
            return stored(job_id, TRUTH_ERRORS)
        except JobNotFoundError:
            return None

    @router.get("/{job_id}/cloud.bin", dependencies=READING, responses={200: {"content": {MEDIA_TYPE: {}}}})
    async def cloud_binary(
        job_id: JobId,
        budget: Annotated[int, Query(ge=0, le=100_000_000, description="at most this many points; 0: all")] = (
            DEFAULT_BUDGET
        ),
    ) -> Response:
        path = await asyncio.to_thread(stored, job_id, "cloud.ply")
        errors = await asyncio.to_thread(errors_of, job_id)
        body = await asyncio.to_thread(cloud_body, path, path.stat().st_mtime, budget, errors)
        return Response(body, media_type=MEDIA_TYPE, headers={"Cache-Control": "private, max-age=3600"})

    @router.get("/{job_id}/mesh.bin", dependencies=READING, responses={200: {"content": {MEDIA_TYPE: {}}}})
    async def mesh_binary(job_id: JobId) -> Response:
        path = await asyncio.to_thread(stored, job_id, "mesh.ply")
        body = await asyncio.to_thread(mesh_body, path, path.stat().st_mtime)
        return Response(body, media_type=MEDIA_TYPE, headers={"Cache-Control": "private, max-age=3600"})

    return router
