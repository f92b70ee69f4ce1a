"""Disk space: what a scan will write, checked before it is queued and again before it runs, and
what makes the data directory a problem for /v1/health."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from rig.assembly import frame_sample_bytes, frames_per_scan
from rig.config import RigConfig
from rig.service.errors import StorageFullError
from rig.service.jobs import JobStore

MB = 1_000_000
RESERVE_BYTES = 64 * MB  # kept free for the job database, its write-ahead log and the journal
# Per camera pixel of a stored scan: a PLY point (xyz and normal float32, rgb, quality, source,
# angle), its depth (16-bit PNG), overlap mask, preview, and its truth error (simulated rigs);
# PNG compresses, so this is an upper bound.
STORED_BYTES_PER_PIXEL = (12 + 12 + 3 + 4 + 1 + 4) + 2 + 1 + 3 + 4
MESH_BYTES_PER_PIXEL = 27 + 2 * 13  # a ring scan's surface: a vertex per pixel, two triangles


def expected_scan_bytes(config: RigConfig, request: dict[str, Any]) -> int:
    """An upper bound of what a scan request writes: a point per camera pixel and projector (every
    pair measures), the images, a ring scan's surface mesh, and the frames uncompressed when kept."""
    pixels = sum(camera.resolution[0] * camera.resolution[1] for camera in config.cameras)
    name = "rings" if request.get("adaptive") or request.get("plan") else request.get("codec") or config.scan.codec
    per_pixel = STORED_BYTES_PER_PIXEL * len(config.projectors) + (MESH_BYTES_PER_PIXEL if name == "rings" else 0)
    total = pixels * per_pixel
    if request.get("keep_frames"):
        frames = sum(frames_per_scan(config, p, name) for p in range(len(config.projectors)))
        for camera in config.cameras:
            total += frames * camera.resolution[0] * camera.resolution[1] * frame_sample_bytes(camera)
    return total


def check_free_space(data_dir: Path, needed: int, what: str) -> None:
    """StorageFullError unless `data_dir` (or, before it is made, the folder it will be made in)
    has room for `needed` bytes and the reserve."""
    existing = next(p for p in (data_dir.absolute(), *data_dir.absolute().parents) if p.is_dir())
    free = shutil.disk_usage(existing).free
    if free < needed + RESERVE_BYTES:
        raise StorageFullError(
            f"{data_dir} has {free / MB:.0f} MB free; {what} needs up to {needed / MB:.0f} MB "
            f"and {RESERVE_BYTES / MB:.0f} MB stay free for the job records: free some space "
            "(delete old scans) and try again"
        )


def storage_problems(data_dir: Path, store: JobStore) -> list[str]:
    """Why the data directory degrades the service: job states held in memory, a full disk."""
    found = []
    unsaved = store.unsaved
    if unsaved:
        found.append(f"{unsaved}; job states are kept in memory until the disk takes them")
    try:
        free = shutil.disk_usage(data_dir).free
    except OSError as exc:
        return [*found, f"{data_dir}: {exc.strerror}"]
    if free < RESERVE_BYTES:
        found.append(f"{data_dir} has {free / MB:.1f} MB free, less than the {RESERVE_BYTES / MB:.0f} MB it keeps free")
    return found
