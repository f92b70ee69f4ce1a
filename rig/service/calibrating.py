"""What a calibration job does: a session on the open rig (simulated views, or the rig's board
views), a projector response measurement, or a calibration from a folder of captures uploaded into
imports (PUT /v1/imports/{folder}/{view}/{file}). The captures are the bench's own layout
(view_NN/<camera>.png, view_NN/<projector>_<camera>/NNN.png, as `slrig calibrate --save-views`
writes it) or another system's (one sub-folder per board pose, its frames as a pattern description
lists them); neither opens a device. The result is written through `<out>.partial`, so `out` is
complete or absent."""

from __future__ import annotations

import fnmatch
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rig.assembly import open_rig
from rig.calibrate import CalibrationOutcome, calibrate, calibrate_described, calibrate_response, calibration_overrides
from rig.config import RigConfig
from rig.opened_rig import Rig
from rig.patterns import PatternSpec
from rig.progress import ProgressCallback, ProgressTracker
from rig.service.errors import ImportRefusedError
from rig.service.imports import folder_path, pattern_description
from rig.store import publish_folder

VIEW_PREFIX = "view_"  # the bench's own layout: one view_NN folder per board pose


def calibration_settings(config: RigConfig, request: dict[str, Any]) -> RigConfig:
    """The config with the request's board and lens models; ConfigError names `board` or `model`."""
    models = (request.get("camera_model"), request.get("projector_model"))
    board, model, world = request.get("board"), request.get("model"), request.get("world")
    return calibration_overrides(config, board, model, ("board", "model"), models, world)


def captured_views(data_dir: Path, request: dict[str, Any]) -> tuple[Path, PatternSpec | Path | None]:
    """The imports folder a request's `images` names and its pattern description (None: the bench's
    own layout). Refusals name the request's field: a folder that is not there (404), one without
    views or a description that cannot calibrate a projector (422)."""
    folder = folder_path(data_dir, request["images"])
    if request.get("patterns") is None:
        if not any(d.is_dir() and d.name.startswith(VIEW_PREFIX) for d in folder.iterdir()):
            raise ImportRefusedError(
                f"images: imports folder {folder.name!r} has no view_NN sub-folders (view_00/<camera>.png, "
                "view_00/<projector>_<camera>/NNN.png); another system's captures need patterns"
            )
        return folder, None
    patterns, spec = pattern_description(data_dir, folder.name, request["patterns"])
    glob = request.get("view_glob", "*")
    if not any(d.is_dir() and fnmatch.fnmatch(d.name, glob) for d in folder.iterdir()):
        raise ImportRefusedError(
            f"images: imports folder {folder.name!r} has no sub-folders matching view_glob {glob!r} "
            "(one per board pose)"
        )
    if len(spec.axes) != 2:
        raise ImportRefusedError(
            f"patterns: the description codes only {spec.axes[0]}; a projector's calibration needs columns and rows"
        )
    return folder, patterns


def calibration_to_directory(
    open_the_rig: Callable[[], Rig],
    config: RigConfig,
    data_dir: Path,
    request: dict[str, Any],
    out: Path,
    progress: ProgressCallback | None = None,
) -> dict[str, Any]:
    """A calibration request (see CalibrationRequest) written into `out`: its summary and files.
    `open_the_rig` is called only for a session that captures."""
    tracker = ProgressTracker(progress)
    tracker.report("capture" if "images" not in request else "analyse", 0.05)
    partial = out.with_name(out.name + ".partial")
    what = request["what"]
    try:
        if what == "response":
            document = calibrate_response(open_the_rig(), partial)
            summary: dict[str, Any] = {"projectors": document["projectors"]}
        else:
            settings, part = calibration_settings(config, request), tracker.part(0.05, 0.95)
            outcome = _geometric(open_the_rig, settings, data_dir, request, partial, part)
            summary = {"sha256": outcome.sha256, "views": outcome.views, "report": outcome.report}
        files = sorted(p.name for p in partial.iterdir() if p.is_file()) if partial.is_dir() else []
        if partial.is_dir():
            publish_folder(partial, out)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    tracker.report("done", 1.0)
    return {**summary, "files": files}


def _geometric(
    open_the_rig: Callable[[], Rig],
    config: RigConfig,
    data_dir: Path,
    request: dict[str, Any],
    partial: Path,
    progress: ProgressCallback | None,
) -> CalibrationOutcome:
    what = request["what"]
    if "images" not in request:
        views = request.get("views")
        return calibrate(open_the_rig(), what, partial, views, settings=config.calibration, progress=progress)
    folder, patterns = captured_views(data_dir, request)
    if patterns is not None:
        glob, source = request.get("view_glob", "*"), request.get("board_image", "auto")
        return calibrate_described(config, folder, patterns, partial, what, glob, source, progress)
    with open_rig(config, with_devices=False) as geometry:  # the views are files: no device
        return calibrate(geometry, what, partial, images=folder, progress=progress)
