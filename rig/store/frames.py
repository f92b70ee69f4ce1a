"""A folder of frames another system captured, read as its pattern description (a YAML file,
rig.patterns.spec) lists them: in order, checked (every frame there, readable, one size), at its
bit depth, in grey. Each frame's size is checked from its header before it is decoded, so that a
small file that decodes to gigabytes (a decompression bomb) is refused without being decoded."""

from __future__ import annotations

import glob
import hashlib
import re
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import overload

import cv2
import numpy as np
import yaml
from pydantic import ValidationError

from rig.config import validation_problems
from rig.errors import FramesError, PatternSpecError
from rig.patterns import FrameFiles, PatternSpec
from rig.store.image_header import ImageHeader, check_image_size, image_header_bytes, read_image_header

_GREY = {"red": 2, "green": 1, "blue": 0}  # channels as OpenCV reads them (BGR)
READERS = 4
# Larger than any scanner camera's frame (a 16-bit one decodes to 128 MB); a 20000x20000 bomb is refused.
MAX_FRAME_PIXELS = 64_000_000


@dataclass(frozen=True, eq=False)
class FrameSet:
    frames: Sequence[np.ndarray]  # (H, W) uint8 or uint16, in the description's order
    files: list[Path]
    full_scale: int  # 255 or 65535
    digests: dict[str, str] | None = None  # read_frames' hashes; open_frames' come with its frames

    @property
    def sha256(self) -> dict[str, str]:
        """File name -> its content's hash, for the manifest."""
        if isinstance(self.frames, ArrivingFrames):
            return self.frames.sha256()
        assert self.digests is not None
        return self.digests


class ArrivingFrames(Sequence[np.ndarray]):
    """Frames being read on threads, each one there as soon as it is read: a decoder that walks
    them in order decodes while the rest are read. A frame that cannot be read, or differs from the
    first in size or depth, raises FramesError when it is reached; the first frame's header is
    checked at once, each other's before it is decoded."""

    def __init__(self, paths: list[Path], grey: str, resolution: tuple[int, int] | None = None) -> None:
        self._paths = paths
        first = (paths[0], _checked(paths[0], _header(paths[0]), resolution, None))
        pool = ThreadPoolExecutor(max_workers=READERS)
        self._pending = [pool.submit(_read, path, grey, first, resolution) for path in paths]
        pool.shutdown(wait=False)  # the threads end when the last frame is read
        self._first, _ = self._pending[0].result()

    def __len__(self) -> int:
        return len(self._paths)

    @overload
    def __getitem__(self, index: int) -> np.ndarray: ...

    @overload
    def __getitem__(self, index: slice) -> list[np.ndarray]: ...

    def __getitem__(self, index: int | slice) -> np.ndarray | list[np.ndarray]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        frame, _ = self._pending[index].result()
        if frame.shape != self._first.shape or frame.dtype != self._first.dtype:
            first = self._paths[0].name
            raise FramesError(
                f"frame {self._paths[index]}: {_kind(frame)}, the first frame ({first}) is {_kind(self._first)}"
            )
        return frame

    def sha256(self) -> dict[str, str]:
        return {path.name: pending.result()[1] for path, pending in zip(self._paths, self._pending, strict=True)}


def load_pattern_spec(path: Path) -> PatternSpec:
    """The description in the YAML file `path`; PatternSpecError naming each field at fault."""
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError, RecursionError) as exc:
        raise PatternSpecError(str(path), [f"cannot be read: {exc}"]) from None
    try:
        return PatternSpec.model_validate(data)
    except ValidationError as exc:
        raise PatternSpecError(str(path), validation_problems(exc)) from None


def frame_files(folder: Path, files: FrameFiles, expected: int, breakdown: str = "") -> list[Path]:
    """The frame files in order; FramesError where the folder and the description disagree."""
    if not folder.is_dir():
        raise FramesError(f"frames folder {folder}: not a folder")
    if isinstance(files.files, list):  # names and globs in order: one glob per frequency, say
        found, missing = [], []
        for entry in files.files:
            if glob.has_magic(entry):
                matched = _matching(folder, entry)
                found += matched
                missing += [] if matched else [f"{entry} (no file matches)"]
            else:
                found.append(folder / entry)
                missing += [] if (folder / entry).is_file() else [entry]
        if missing:
            raise FramesError(f"frames folder {folder}: missing {', '.join(missing[:5])}")
    else:
        found = _matching(folder, files.files)
    if len(found) != expected:
        names = ", ".join(p.name for p in found[expected:][:5])
        detail = f" (beyond them: {names})" if len(found) > expected else ""
        listed = "are listed" if isinstance(files.files, list) else f"match {files.files!r}"
        raise FramesError(
            f"frames folder {folder}: the pattern description has {expected} frames{breakdown}, "
            f"{len(found)} files {listed}{detail}"
        )
    return found


def _matching(folder: Path, pattern: str) -> list[Path]:
    return sorted((p for p in folder.glob(pattern) if p.is_file()), key=natural_order)


def open_frames(
    folder: Path, files: FrameFiles, expected: int, resolution: tuple[int, int] | None = None, breakdown: str = ""
) -> FrameSet:
    """The frames of `folder` as they arrive (ArrivingFrames): read on threads while they are used.
    `resolution` (width, height), where the caller knows the camera's, is required of every frame."""
    paths = frame_files(folder, files, expected, breakdown)
    frames = ArrivingFrames(paths, files.grey, resolution)
    return FrameSet(frames, paths, 65535 if frames[0].dtype == np.uint16 else 255)


def read_frames(
    folder: Path, files: FrameFiles, expected: int, resolution: tuple[int, int] | None = None, breakdown: str = ""
) -> FrameSet:
    """The frames of `folder`, all read (on a few threads: PNG decoding releases the GIL), every
    header checked before any is decoded. `resolution` (width, height), where the caller knows the
    camera's, is required of every frame."""
    paths = frame_files(folder, files, expected, breakdown)
    head = (paths[0], _checked(paths[0], _header(paths[0]), resolution, None))
    for path in paths[1:]:
        _checked(path, _header(path), resolution, head)
    with ThreadPoolExecutor(max_workers=READERS) as pool:
        loaded = list(pool.map(lambda p: _read(p, files.grey, head, resolution), paths))
    frames = [frame for frame, _ in loaded]
    first = frames[0]
    for path, frame in zip(paths, frames, strict=True):
        _same_kind(path, frame, paths[0], first)
    full_scale = 65535 if first.dtype == np.uint16 else 255
    return FrameSet(frames, paths, full_scale, {p.name: digest for p, (_, digest) in zip(paths, loaded, strict=True)})


def _same_kind(path: Path, frame: np.ndarray, first_path: Path, first: np.ndarray) -> None:
    if frame.shape != first.shape or frame.dtype != first.dtype:
        raise FramesError(f"frame {path}: {_kind(frame)}, the first frame ({first_path.name}) is {_kind(first)}")


def _kind(frame: np.ndarray) -> str:
    return f"{frame.shape[1]}x{frame.shape[0]} {8 * frame.itemsize}-bit"


def _header(path: Path, data: bytes | None = None) -> ImageHeader:
    """The frame's header from its file (a few KB read) or from its bytes, read already."""
    try:
        return read_image_header(path) if data is None else image_header_bytes(data, str(path))
    except FramesError as exc:  # its message begins with the path
        raise FramesError(f"frame {exc}") from None


def _checked(
    path: Path, header: ImageHeader, resolution: tuple[int, int] | None, first: tuple[Path, ImageHeader] | None
) -> ImageHeader:
    """`header`, if the frame is within MAX_FRAME_PIXELS, of `resolution` and of the first frame's size."""
    check_image_size(header, f"frame {path}", resolution, MAX_FRAME_PIXELS)
    if first is not None and header.size != first[1].size:
        raise FramesError(f"frame {path}: {_stored(header)}, the first frame ({first[0].name}) is {_stored(first[1])}")
    return header


def _stored(header: ImageHeader) -> str:
    return f"{header.width}x{header.height} {header.bits_per_sample}-bit"


def _read(
    path: Path, grey: str, first: tuple[Path, ImageHeader], resolution: tuple[int, int] | None
) -> tuple[np.ndarray, str]:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FramesError(f"frame {path}: cannot be read ({exc.strerror})") from None
    # the bytes decoded are the bytes checked (a file may be replaced after its header was read)
    _checked(path, _header(path, data), resolution, first)
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:  # OpenCV's own limits (drivers/__init__.py), past the header's check
        raise FramesError(f"frame {path}: OpenCV refused to decode it ({exc.err.strip() or exc})") from None
    if image is None:
        raise FramesError(f"frame {path}: not an image OpenCV can read")
    if image.dtype not in (np.uint8, np.uint16):
        raise FramesError(f"frame {path}: {image.dtype} pixels; frames are 8- or 16-bit")
    if image.ndim == 3:
        image = _to_grey(image[..., :3], grey)
    return image, hashlib.sha256(data).hexdigest()


def _to_grey(image: np.ndarray, grey: str) -> np.ndarray:
    if grey == "luminance":
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if grey == "mean":
        return (image.astype(np.float32).mean(axis=2) + 0.5).astype(image.dtype)
    return np.ascontiguousarray(image[..., _GREY[grey]])


def natural_order(path: Path) -> list[object]:
    """Sort key: numbers in a name by value (frame_2 before frame_10)."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]
