"""Recognition of stored scans: a scan directory's descriptor, gallery changes and identification,
shared by the CLI and the daemon.

A scan's surface is its mesh (the surface between the rings, for ring scans) and its cloud
together; the rings are centred about the projector's axis of its first pair (from the manifest's
config and calibration), so the apex is sought along that axis.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.assembly import rig_geometry
from rig.config import config_from_dict
from rig.errors import RecognitionError, SlrigError
from rig.recognition import (
    EMPTY_GALLERY,
    GALLERY_NAME,
    Comparison,
    Descriptor,
    DescriptorSettings,
    Entry,
    Gallery,
    Identification,
    describe,
    matrix_of,
)
from rig.store import read_cloud_ply, read_mesh_vertices

# below these scores a probe is "unknown": the equal-error thresholds bench/recognition.py measured
# for the default descriptor (standardised) and the published one (raw) on the face set scanned
# with 32 rings (README, Recognition)
DEFAULT_THRESHOLDS: dict[Comparison, float] = {"standardised": 0.214, "raw": 0.9998}


@dataclass(frozen=True, eq=False)
class ScanSurface:
    scan_id: str
    points: np.ndarray  # (N, 3) mm
    toward_viewer: np.ndarray  # (3,) unit: the projector's axis, from the surface toward it


def gallery_path(data_dir: Path) -> Path:
    return data_dir / GALLERY_NAME


def scan_surface(folder: Path) -> ScanSurface:
    """The surface a stored scan saw; RecognitionError where the folder is not a readable scan."""
    try:
        manifest = json.loads((folder / "manifest.json").read_text())
        files = manifest["files"]
        parts = [read_cloud_ply((folder / files["cloud"]).read_bytes(), str(folder / files["cloud"])).points]
        if files.get("surface", {}).get("mesh"):
            mesh = folder / files["surface"]["mesh"]
            parts.append(read_mesh_vertices(mesh.read_bytes(), str(mesh)))
        config = config_from_dict(manifest["config"], f"scan {manifest.get('scan_id', folder.name)}")
        projector = [p.name for p in config.projectors].index(manifest["pairs"][0]["projector"])
    except (OSError, ValueError, KeyError, IndexError, TypeError, SlrigError) as exc:
        raise RecognitionError(f"{folder} is not a readable scan directory ({exc})") from None
    _, projectors = rig_geometry(config)
    points = np.concatenate(parts)
    if len(points) == 0:
        raise RecognitionError(f"scan {manifest['scan_id']} has no points")
    model = projectors[projector]
    axis = -np.asarray(model.axis, float)  # the optical axis points away from the projector
    return ScanSurface(str(manifest["scan_id"]), points, axis / np.linalg.norm(axis))


def describe_scan(folder: Path, settings: DescriptorSettings) -> tuple[str, Descriptor]:
    surface = scan_surface(folder)
    return surface.scan_id, describe(surface.points, surface.toward_viewer, settings)


def gallery_add(gallery: Gallery, folder: Path, label: str, settings: DescriptorSettings | None) -> Entry:
    """Describe the scan in `folder` with the gallery's settings (or `settings` for an empty
    gallery; differing ones are refused) and add it under `label`."""
    own = gallery.settings()
    if settings is not None:
        gallery.check_settings(settings)
    chosen = own or settings or DescriptorSettings()
    scan_id, descriptor = describe_scan(folder, chosen)
    return gallery.add(label, scan_id, descriptor)


def identify_scan(
    gallery: Gallery, folder: Path, top: int, threshold: float | None, comparison: Comparison = "standardised"
) -> tuple[str, Identification]:
    """`folder`'s scan identified against the gallery; `threshold` None: the default for the
    comparison made (a gallery of fewer than 3 entries is compared raw)."""
    settings = gallery.settings()
    if settings is None:
        raise RecognitionError(EMPTY_GALLERY)
    scan_id, descriptor = describe_scan(folder, settings)
    limit = DEFAULT_THRESHOLDS if threshold is None else threshold
    return scan_id, matrix_of(gallery).identify(descriptor.features, top, limit, comparison)


def settings_from(options: dict[str, Any]) -> DescriptorSettings | None:
    """Descriptor settings from the options given (None where none was); RecognitionError naming a bad one."""
    given = {k: v for k, v in options.items() if v is not None}
    if not given:
        return None
    try:
        settings = DescriptorSettings(**given)
    except (TypeError, ValueError) as exc:
        raise RecognitionError(f"descriptor settings: {exc}") from None
    return settings
