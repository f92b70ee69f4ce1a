"""An archive's inputs: scan directories that kept their frames, and folders of frames with a pattern
description (another system's captures), each reprocessed into its own output directory of the
same name. An input's digest covers every byte the reprocessing reads (the manifest and the frames,
or the folder's files) and the calibration it is given, so an output made from the same input is
recognised and skipped, and one made from another is never overwritten."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from rig.errors import UsageError
from rig.store import DESCRIPTION_NAME

CHUNK_BYTES = 1 << 20
DIGEST_KEY = "batch_input_sha256"  # in an output's manifest, under origin


@dataclass(frozen=True)
class ArchiveInput:
    """One scan to reprocess: `layout` "scan" (a scan directory with kept frames) or "frames" (a
    folder of frames with its pattern description)."""

    path: Path
    layout: Literal["scan", "frames"]

    @property
    def name(self) -> str:
        return self.path.name


def input_layout(path: Path) -> Literal["scan", "frames"] | None:
    if (path / "manifest.json").is_file():
        return "scan"
    if (path / DESCRIPTION_NAME).is_file():
        return "frames"
    return None


def find_inputs(paths: Sequence[Path]) -> list[ArchiveInput]:
    """Each path an input itself, or a folder whose sub-folders are inputs (an archive, a data
    directory's scans/); refused (UsageError) when a path is neither, or two inputs would write
    the same output."""
    found: list[ArchiveInput] = []
    for path in paths:
        layout = input_layout(path)
        if layout is not None:
            found.append(ArchiveInput(path, layout))
            continue
        if not path.is_dir():
            raise UsageError(f"{path}: no such folder")
        inside = [ArchiveInput(p, k) for p in sorted(path.iterdir()) if p.is_dir() and (k := input_layout(p))]
        if not inside:
            raise UsageError(
                f"{path}: neither a scan directory (manifest.json), nor a frames folder ({DESCRIPTION_NAME}), "
                "nor a folder of them"
            )
        found.extend(inside)
    by_name: dict[str, Path] = {}
    for item in found:
        if item.name in by_name:
            raise UsageError(f"{by_name[item.name]} and {item.path}: both would be written to {item.name} under --out")
        by_name[item.name] = item.path
    return found


def input_files(item: ArchiveInput) -> list[Path]:
    """The files the reprocessing of `item` reads, in a fixed order."""
    if item.layout == "frames":
        return sorted(p for p in item.path.iterdir() if p.is_file())
    manifest = json.loads((item.path / "manifest.json").read_text())
    files = manifest.get("files") or {}
    stored = files.get("frames") or {}
    frames = [item.path / name for key in sorted(stored) for name in stored[key]]
    masks = [item.path / name for _, name in sorted((files.get("adaptive_projection") or {}).items())]
    return [item.path / "manifest.json", *frames, *masks]  # an adaptive scan's masks: reprocessing reads them


def input_digest(item: ArchiveInput, calibration: Sequence[Path] = ()) -> str:
    """sha256 over the names and bytes of everything the reprocessing reads (see the docstring)."""
    digest = hashlib.sha256()
    for label, files in (("input", input_files(item)), ("calibration", sorted(_files(calibration)))):
        digest.update(label.encode())
        for path in files:
            digest.update(f"\0{path.name}\0".encode())
            with path.open("rb") as stream:
                while chunk := stream.read(CHUNK_BYTES):
                    digest.update(chunk)
    return digest.hexdigest()


def _files(paths: Sequence[Path]) -> list[Path]:
    out: list[Path] = []
    for path in paths:
        out.extend(sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path])
    return out


def output_digest(target: Path) -> str | None:
    """The input digest an output directory was made from (None: not made by a batch, or unreadable)."""
    try:
        manifest = json.loads((target / "manifest.json").read_text())
    except (OSError, ValueError):
        return None
    origin = manifest.get("origin") or {}
    found = origin.get(DIGEST_KEY) or (origin.get("reconstructed") or {}).get(DIGEST_KEY)
    return found if isinstance(found, str) else None
