"""Calibration views from another system's capture folders: one folder per board pose, its frames
as a pattern description (rig.patterns.spec) lists them. No device is opened.

    <dir>/capture_0/graycode_00.png ... graycode_41.png     one board pose
    <dir>/capture_1/...

The board is found in the white frame, or where the description has none, in an image made from
the coded frames: their mean (a lit and an unlit frame of every bit average to half white) or
their modulation (brightest minus darkest, which the ambient light does not reach). Projector
coordinates at the board's corners come from the decoded frames by local homographies, as for
slrig's own views.
"""

from __future__ import annotations

import fnmatch
from pathlib import Path
from typing import Literal

import numpy as np

from rig.calibrate.boards import Board
from rig.calibrate.views import View, projector_corners
from rig.errors import CalibrationError, FramesError
from rig.patterns import PatternSpec, decode_described
from rig.progress import ProgressCallback, ProgressTracker
from rig.store import natural_order, read_frames

BoardImage = Literal["auto", "white", "mean", "modulation"]


def board_image(frames: list[np.ndarray], spec: PatternSpec, source: BoardImage) -> np.ndarray:
    """The 8-bit image the board is detected in: the white frame (auto, where there is one), the
    frames' mean (auto otherwise) or their modulation, stretched so its brightest 0.5 % are white."""
    roles = spec.roles()
    whites = [i for i, role in enumerate(roles) if role.shows == "white"]
    if source == "white" and not whites:
        raise CalibrationError("--board-image white: the pattern description has no white frame")
    if source in ("auto", "white") and whites:
        image = frames[whites[0]].astype(np.float32)
    elif source == "modulation":
        stack = np.stack(frames)
        image = (stack.max(axis=0) - stack.min(axis=0)).astype(np.float32)
    else:
        image = np.mean(np.stack(frames), axis=0, dtype=np.float32)
    top = max(float(np.percentile(image, 99.5)), 1.0)
    return np.clip(image * (255.0 / top), 0, 255).astype(np.uint8)


def view_folders(folder: Path, pattern: str) -> list[Path]:
    """The sub-folders of `folder` whose names match `pattern`, in natural order."""
    if not folder.is_dir():
        raise CalibrationError(f"--images: no such folder: {folder}")
    found = sorted((d for d in folder.iterdir() if d.is_dir() and fnmatch.fnmatch(d.name, pattern)), key=natural_order)
    if not found:
        raise CalibrationError(f"--images: {folder} has no sub-folders matching {pattern!r} (one per board pose)")
    return found


def load_described_views(
    folders: list[Path],
    spec: PatternSpec,
    board: Board,
    source: BoardImage = "auto",
    progress: ProgressCallback | None = None,
) -> tuple[list[View], tuple[int, int]]:
    """One view per folder (camera 0, projector 0) and the camera's (width, height). FramesError
    names a folder whose frames the description does not list, or whose size differs."""
    if len(spec.axes) != 2:
        raise CalibrationError(
            f"the pattern description codes only {spec.axes[0]}; a projector's calibration needs "
            "columns and rows (gray.axes or phase.axes)"
        )
    views, size = [], None
    tracker = ProgressTracker(progress)
    for index, folder in enumerate(folders):
        tracker.report("views", index / len(folders), f"view {index + 1} of {len(folders)}: {folder.name}")
        frames = read_frames(folder, spec.frames, len(spec.roles()), breakdown=spec.frame_breakdown())
        height, width = frames.frames[0].shape
        if size is not None and size != (width, height):
            first = f"{size[0]}x{size[1]}"
            raise FramesError(f"frames folder {folder}: {width}x{height} frames, the first view's are {first}")
        size = (width, height)
        view = View(index, label=folder.name)
        image = board_image(frames.frames, spec, source)
        view.white[0] = image
        detection = board.detect(image)
        if len(detection):
            view.camera[0] = detection
            corners = projector_corners(decode_described(frames.frames, spec, frames.full_scale), detection)
            if len(corners):
                view.projector[(0, 0)] = corners
        views.append(view)
    assert size is not None
    return views, size
