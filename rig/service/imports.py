"""Files a client uploads for reconstruction or calibration (`PUT /v1/imports/{folder}/{file}`):
frames, a pattern description, a calibration file, kept in <data_dir>/imports/<folder>/ until the
folder is deleted; calibration captures in sub-folders (`view_03/cam0.png`,
`view_03/proj0_cam0/000.png`, at most MAX_DEPTH folders below the import's). Each file is written
atomically; every part of a path is a plain name and the file's has a known suffix, so no upload
can reach outside its folder. An upload is refused before it is written when its body is empty,
its folder would grow past its limit, the disk would keep less than the job records' reserve, or
an image's header gives more pixels than allowed (a decompression bomb is never decoded)."""

from __future__ import annotations

import errno
import hashlib
import re
import shutil
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from rig.calibrate import ForeignCalibrationOptions
from rig.config import validation_problems
from rig.errors import FramesError, PatternSpecError
from rig.patterns import PatternSpec
from rig.service.errors import ImportNotFoundError, ImportRefusedError, ImportTooLargeError, StorageFullError
from rig.service.jobs import JOB_ID
from rig.service.space import check_free_space
from rig.store import check_image_size, frame_files, image_header_bytes, load_pattern_spec, write_atomic

IMPORTS = "imports"
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")
SUFFIXES = (".png", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg", ".yaml", ".yml", ".json", ".xml")
MAX_FILE_BYTES = 64 * 1024 * 1024  # a 16-bit 4K frame as TIFF is about 50 MB
MAX_FILES = 2000  # per folder
MAX_DEPTH = 2  # sub-folders: a calibration view, and its projector-camera pair
IMAGE_SUFFIXES = (".png", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg")
_STORING = threading.Lock()


def imports_dir(data_dir: Path) -> Path:
    return data_dir / IMPORTS


def folder_path(data_dir: Path, folder: str) -> Path:
    """An existing imports folder; ImportNotFoundError otherwise."""
    path = imports_dir(data_dir) / folder
    if not NAME.match(folder) or not path.is_dir():
        raise ImportNotFoundError(f"no imports folder {folder!r} (upload its files with PUT /v1/imports/{folder}/FILE)")
    return path


def file_in(data_dir: Path, folder: str, name: str, what: str) -> Path:
    """A file uploaded into `folder`; ImportNotFoundError naming `what` otherwise."""
    path = folder_path(data_dir, folder) / name
    if not NAME.match(name) or not path.is_file():
        raise ImportNotFoundError(f"{what}: no file {name!r} in imports folder {folder!r}")
    return path


def store_file(
    data_dir: Path,
    folder: str,
    name: str,
    data: bytes,
    max_folder_bytes: int = 4 * 1024**3,
    max_image_pixels: int = 64_000_000,
) -> dict[str, Any]:
    """Write one uploaded file; `name` may lead through sub-folders ('view_00/cam0.png'). Refused,
    with nothing written: a name, path or suffix that is refused, an empty body, a full folder
    (ImportRefusedError); a folder that would hold more than `max_folder_bytes`
    (ImportTooLargeError); an image whose header is unreadable or gives more than
    `max_image_pixels` (FramesError); too little free space (StorageFullError)."""
    parts = name.split("/")
    if len(parts) > MAX_DEPTH + 1:
        raise ImportRefusedError(f"file {name!r}: at most {MAX_DEPTH} sub-folders deep")
    for label, value in (("folder", folder), *(("file", part) for part in parts)):
        if not NAME.match(value):
            raise ImportRefusedError(f"{label} {value!r}: letters, digits, '_', '.', '-', at most 100 characters")
    if not name.lower().endswith(SUFFIXES):
        raise ImportRefusedError(f"file {name!r}: the suffix must be one of {', '.join(SUFFIXES)}")
    if not data:
        raise ImportRefusedError(f"file {name!r}: the request body is empty; it must hold the file's bytes")
    if name.lower().endswith(IMAGE_SUFFIXES):
        check_image_size(image_header_bytes(data, name), name, None, max_image_pixels)
    with _STORING:  # the limits judge what is on disk: one upload checked and written at a time
        return _store_checked(data_dir, folder, name, data, max_folder_bytes)


def _store_checked(data_dir: Path, folder: str, name: str, data: bytes, max_folder_bytes: int) -> dict[str, Any]:
    target = imports_dir(data_dir) / folder
    others = [p for p in _files(target) if p != target / name]
    if len(others) >= MAX_FILES:
        raise ImportRefusedError(f"folder {folder!r} holds {MAX_FILES} files already")
    held = sum(p.stat().st_size for p in others)
    if held + len(data) > max_folder_bytes:
        raise ImportTooLargeError(
            f"folder {folder!r} holds {held} bytes; with {name!r} ({len(data)} bytes) it would pass its limit "
            f"of {max_folder_bytes} bytes (service.max_import_bytes)"
        )
    check_free_space(data_dir, len(data), f"file {name!r}")
    if (target / name).is_dir():
        raise ImportRefusedError(f"file {name!r}: a sub-folder of that name holds files already")
    try:
        (target / name).parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise ImportRefusedError(f"file {name!r}: a file of the name of one of its folders is there already") from None
    try:
        write_atomic(target / name, data)
    except OSError as exc:  # the disk filled meanwhile: the temporary file is gone, the old file kept
        if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
            raise
        raise StorageFullError(f"file {name!r}: the disk is full ({exc.strerror}); nothing was stored") from None
    return {"folder": folder, "file": name, "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def list_imports(data_dir: Path) -> list[dict[str, Any]]:
    root = imports_dir(data_dir)
    if not root.is_dir():
        return []
    out = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir() and NAME.match(p.name)):
        files = _files(folder)
        out.append({"folder": folder.name, "files": len(files), "bytes": sum(f.stat().st_size for f in files)})
    return out


def _files(folder: Path) -> list[Path]:
    """The files a folder holds, in its sub-folders too (not the hidden ones a write leaves)."""
    if not folder.is_dir():
        return []
    return [f for f in folder.rglob("*") if f.is_file() and not f.name.startswith(".")]


def remove_folder(data_dir: Path, folder: str) -> None:
    path = folder_path(data_dir, folder)
    doomed = path.with_name(f".{path.name}.deleting")
    shutil.rmtree(doomed, ignore_errors=True)  # an earlier deletion's leftover
    try:
        path.rename(doomed)  # gone from listings at once; a crash leaves a hidden folder that startup removes
    except FileNotFoundError:  # another request deleted it first
        raise ImportNotFoundError(f"no imports folder {folder!r}") from None
    shutil.rmtree(doomed, ignore_errors=True)


def remove_leftovers(data_dir: Path) -> None:
    """Folders a deletion began and a crash interrupted."""
    root = imports_dir(data_dir)
    for doomed in root.glob(".*.deleting") if root.is_dir() else []:
        shutil.rmtree(doomed, ignore_errors=True)


def reconstruction_inputs(
    data_dir: Path, calibration_folder: Callable[[str], Path], request: dict[str, Any]
) -> tuple[Path, PatternSpec | Path, Path | list[Path], ForeignCalibrationOptions]:
    """The frames folder, description, calibration and import options a reconstruction request
    names (see ReconstructionRequest); `calibration_folder` finds a finished calibration job's
    folder by id. Refusals name the request's field."""
    frames = folder_path(data_dir, request["frames"])
    name = request["calibration"]  # what the request names must be there (404) before it is judged (422)
    calibration: Path | list[Path]
    if isinstance(name, list):  # one calibration's files, read together
        calibration = [file_in(data_dir, frames.name, n, "calibration") for n in name]
    else:
        calibration = (
            calibration_folder(name) if JOB_ID.match(name) else file_in(data_dir, frames.name, name, "calibration")
        )
    patterns, spec = pattern_description(data_dir, frames.name, request["patterns"])
    try:
        options = ForeignCalibrationOptions.model_validate(request.get("calibration_options") or {})
    except ValidationError as exc:
        raise ImportRefusedError("calibration_options: " + "; ".join(validation_problems(exc))) from None
    try:
        frame_files(frames, spec.frames, len(spec.roles()), spec.frame_breakdown())
    except FramesError as exc:  # named as the client knows the folder, not by the daemon's path
        raise FramesError(str(exc).replace(f"frames folder {frames}", f"imports folder {frames.name!r}")) from None
    return frames, patterns, calibration, options


def pattern_description(
    data_dir: Path, folder: str, described: dict[str, Any] | str
) -> tuple[PatternSpec | Path, PatternSpec]:
    """A request's `patterns`: a YAML file's name in the imports folder (the path, and the description
    read from it) or the description itself. PatternSpecError names the field at fault."""
    if isinstance(described, str):
        path = file_in(data_dir, folder, described, "patterns")
        try:
            return path, load_pattern_spec(path)
        except PatternSpecError as exc:  # named as the client knows the file, not by the daemon's path
            raise PatternSpecError("patterns", [f"patterns ({described}) {p}" for p in exc.problems]) from None
    try:
        spec = PatternSpec.model_validate(described)
    except ValidationError as exc:
        raise PatternSpecError("patterns", [f"patterns.{p}" for p in validation_problems(exc)]) from None
    return spec, spec
