"""The memory a scan of a rig needs, estimated from its resolutions before anything is allocated:
a rig this machine cannot hold is refused naming the field (ConfigError), instead of exhausting
memory halfway through a scan.

The coefficients were measured (peak RSS of scans at several camera and projector resolutions,
each codec; `python bench/memory_model.py`) and rounded up: what a scan holds per camera pixel
(frames, decoding, triangulation, the cloud), per projector pixel (its patterns, the decoder's
tables), and what the simulated bench adds per pixel (its ray cast, lighting and rendering).
"""

from __future__ import annotations

import os
from pathlib import Path

from rig.config import CameraConfig, RigConfig
from rig.errors import ConfigError
from rig.patterns import codec_class

GB = 1_000_000_000
# Measured on the simulated bench (`python bench/memory_model.py`, 27 scans: gray, phase, rings;
# cameras 640x512 to 2560x2048, projectors 512x384 to 2048x1536; numba's loops and decision 0016
# included): a least-squares fit gives 280 MB + 256 B per camera pixel (its ~22 frames included) +
# 30 B per projector pixel. The coefficients below put every measured peak under its estimate
# (1.04 to 1.72 times it, 1.24 on average): ring scans with a small camera and a large projector
# (the ring plan and its patterns at the projector's resolution) set the projector's share.
FIXED_BYTES = 300_000_000  # the interpreter, numpy, OpenCV, numba, the web stack: a process before a scan
CAMERA_BYTES_PER_PIXEL = 150  # per camera pixel and projector lighting it: decode, triangulate, cloud
SIM_CAMERA_BYTES_PER_PIXEL = 120  # the simulated bench per camera pixel: rays, hits, lighting, render
PROJECTOR_BYTES_PER_PIXEL = 70  # per projector pixel: the patterns, the decoder's tables, ring plans
SIM_PROJECTOR_BYTES_PER_PIXEL = 20  # the simulated projector's images and the light of the last two


def frames_per_scan(config: RigConfig, projector: int, codec: str | None = None) -> int:
    """Frames a scan with `codec` (default: the config's) projects from one projector."""
    name = codec or config.scan.codec
    params = getattr(config.scan, name, None)
    return codec_class(name)(tuple(config.projectors[projector].resolution), params, None).frame_count


def frame_sample_bytes(camera: CameraConfig) -> int:
    """Bytes per pixel of one of the camera's frames: channels times the sample's bytes."""
    return (3 if camera.color else 1) * (2 if camera.bit_depth > 8 else 1)


def scan_memory(config: RigConfig) -> dict[str, int]:
    """Bytes a scan of `config` needs, by the field that causes them (beside FIXED_BYTES)."""
    simulated = config.simulated
    frames = [frames_per_scan(config, p) for p in range(len(config.projectors))]
    needs: dict[str, int] = {}
    for c, camera in enumerate(config.cameras):
        pixels = camera.resolution[0] * camera.resolution[1]
        held = pixels * (sum(frames) * frame_sample_bytes(camera) + CAMERA_BYTES_PER_PIXEL * len(config.projectors))
        needs[f"cameras[{c}].resolution"] = held + (pixels * SIM_CAMERA_BYTES_PER_PIXEL if simulated else 0)
    for p, projector in enumerate(config.projectors):
        pixels = projector.resolution[0] * projector.resolution[1]
        per_pixel = PROJECTOR_BYTES_PER_PIXEL + (SIM_PROJECTOR_BYTES_PER_PIXEL if simulated else 0)
        needs[f"projectors[{p}].resolution"] = pixels * per_pixel
    return needs


def available_memory() -> int | None:
    """Memory this process can take without swapping: the system's MemAvailable, or less where a
    cgroup (a container, a systemd MemoryMax=) limits it; None where unknown."""
    system = _meminfo_available()
    limited = _cgroup_room()
    known = [value for value in (system, limited) if value is not None]
    return min(known) if known else None


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):
        return None


def _cgroup_room(root: str = "/sys/fs/cgroup", own: str = "/proc/self/cgroup") -> int | None:
    """The limit less the usage of this process's memory cgroup (v2, or v1's memory controller),
    or None where there is no limit."""
    try:
        with open(own, encoding="ascii") as cgroups:
            lines = [line.strip().split(":", 2) for line in cgroups if line.count(":") >= 2]
    except OSError:
        return None
    for _, controllers, path in lines:
        if "memory" in controllers.split(","):  # v1
            files = (f"{root}/memory{path}".rstrip("/") + "/memory.limit_in_bytes", "memory.usage_in_bytes")
            break
    else:
        path = next((p for _, c, p in lines if c == ""), None)
        if path is None:
            return None
        files = (f"{root}{path}".rstrip("/") + "/memory.max", "memory.current")
    limit_file, usage_name = files
    try:
        with open(limit_file, encoding="ascii") as limit:
            text = limit.read().strip()
        if text == "max" or int(text) >= 1 << 60:  # v1 writes "no limit" as a number near 2**63
            return None
        with open(str(Path(limit_file).with_name(usage_name)), encoding="ascii") as usage:
            return max(0, int(text) - int(usage.read().strip()))
    except (OSError, ValueError):
        return None


def check_memory(config: RigConfig, available: int | None = None) -> None:
    """ConfigError naming the resolution that needs the most when a scan needs more memory than
    is available."""
    available = available_memory() if available is None else available
    if available is None:
        return
    needs = scan_memory(config)
    total = FIXED_BYTES + sum(needs.values())
    if total <= available:
        return
    field = max(needs, key=needs.__getitem__)
    raise ConfigError(
        field,
        [
            f"{field}: a scan of this rig needs about {total / GB:.1f} GB of memory ({needs[field] / GB:.1f} GB "
            f"for this device), more than the {available / GB:.1f} GB this machine has available; "
            "use a lower resolution (or a region of interest) or a machine with more memory"
        ],
    )
