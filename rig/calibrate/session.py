"""One calibration run, from views to files: the library call behind `slrig calibrate`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from rig.calibrate.boards import Board
from rig.calibrate.check import board_checks
from rig.calibrate.described import BoardImage, load_described_views, view_folders
from rig.calibrate.files import write_calibration
from rig.calibrate.report import coverage_png, report, residuals_png, view_caption, view_jpeg
from rig.calibrate.solve import DeviceCalibration, calibrate_cameras, calibrate_projectors
from rig.calibrate.views import View, capture_placed_views, default_poses, load_folder_views
from rig.calibrate.world import World, reframed, refuse_camera_world_for_the_bench, world_check
from rig.config import BoardPose, CalibrationConfig, RigConfig
from rig.errors import CalibrationError
from rig.opened_rig import Rig
from rig.patterns import PatternSpec
from rig.progress import ProgressCallback, ProgressTracker
from rig.store import load_pattern_spec, write_atomic

Mode = Literal["camera", "projector", "rig"]


@dataclass
class CalibrationOutcome:
    devices: list[DeviceCalibration]
    report: dict[str, Any]
    sha256: str
    folder: Path
    views: int


def collect_views(
    rig: Rig,
    board: Board,
    mode: Mode,
    views: int,
    images: Path | None = None,
    save_views: Path | None = None,
    given: list[BoardPose] | None = None,
    progress: ProgressCallback | None = None,
) -> list[View]:
    """The views read from `images`, or captured at the `given` poses (else at `views` poses spread
    around where the cameras look)."""
    with_projectors = mode != "camera"
    if images is not None:
        return load_folder_views(rig, board, images, with_projectors, progress)
    if given is not None:
        poses = [(_euler(p.rotation_deg), np.array(p.center_mm, float)) for p in given]
    else:
        centre = np.mean([c.geometry.pose.look_at_mm for c in rig.config.cameras], axis=0)
        poses = default_poses(views, centre)
    return capture_placed_views(rig, board, poses, with_projectors, save_views, progress)


def _euler(degrees: tuple[float, float, float]) -> np.ndarray:
    rx, ry, rz = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return z @ y @ x


def calibrate(
    rig: Rig,
    mode: Mode,
    out: Path,
    views: int | None = None,
    images: Path | None = None,
    save_views: Path | None = None,
    settings: CalibrationConfig | None = None,
    progress: ProgressCallback | None = None,
) -> CalibrationOutcome:
    """Capture (or read) views, calibrate, and write the files into `out`. `camera` calibrates the
    cameras; `projector` and `rig` also the projectors (which need the cameras). `settings` (board,
    model, views, poses) replace the config's calibration section. Raises CalibrationError, having
    written nothing, when the views cannot give a calibration."""
    config = rig.config
    settings = settings or config.calibration
    refuse_camera_world_for_the_bench(config, out, settings.world)
    board = Board(settings.board)
    tracker = ProgressTracker(progress)
    count, poses = views or settings.views, settings.poses
    collected = collect_views(rig, board, mode, count, images, save_views, poses, tracker.part(0.0, 0.7))
    cameras = [(c.name, c.resolution) for c in config.cameras]
    projectors = [(p.name, p.resolution) for p in config.projectors] if mode != "camera" else []
    return solve_and_write(collected, board, cameras, projectors, settings.models, out, tracker, settings.world)


def calibrate_described(
    config: RigConfig,
    images: Path,
    patterns: Path | PatternSpec,
    out: Path,
    mode: Mode = "rig",
    view_glob: str = "*",
    source: BoardImage = "auto",
    progress: ProgressCallback | None = None,
) -> CalibrationOutcome:
    """Calibrate the config's first camera (and projector) from another system's capture folders
    under `images`, described by the pattern description `patterns` (or its YAML file); no device is
    opened."""
    spec = patterns if isinstance(patterns, PatternSpec) else load_pattern_spec(patterns)
    refuse_camera_world_for_the_bench(config, out, config.calibration.world)
    board = Board(config.calibration.board)
    tracker = ProgressTracker(progress)
    folders = view_folders(images, view_glob)
    collected, camera_size = load_described_views(folders, spec, board, source, tracker.part(0.0, 0.7))
    cameras = [(config.cameras[0].name, camera_size)]
    projectors = [(config.projectors[0].name, spec.projector.resolution)] if mode != "camera" else []
    models, world = config.calibration.models, config.calibration.world
    return solve_and_write(collected, board, cameras, projectors, models, out, tracker, world)


def solve_and_write(
    collected: list[View],
    board: Board,
    cameras: list[tuple[str, tuple[int, int]]],
    projectors: list[tuple[str, tuple[int, int]]],
    models: tuple[str, str],
    out: Path,
    tracker: ProgressTracker | None = None,
    world: World = "board",
) -> CalibrationOutcome:
    """Calibrate the named devices from the views (`models`: the cameras' and the projectors' lens
    models) and write the files into `out`; `tracker` hears
    of the solve (from 0.7 of the whole, the views before it) and its end."""
    tracker = tracker or ProgressTracker(None)
    tracker.report("solve", 0.7, f"{len(collected)} views")
    if not any(v.camera for v in collected):
        cols, rows = board.config.squares
        raise CalibrationError(
            f"no view shows the {cols}x{rows}-square {board.config.kind} board that the config "
            "describes (calibration.board): wrong board, or not in view"
        )
    camera_model, projector_model = models
    devices = calibrate_cameras(collected, board, [n for n, _ in cameras], [s for _, s in cameras], camera_model)
    if projectors:
        names, sizes = [n for n, _ in projectors], [s for _, s in projectors]
        devices += calibrate_projectors(collected, board, devices, names, sizes, projector_model)
    devices, rotation, translation = reframed(devices, world)  # the board frame in the world: R X + t
    summary = report(devices)
    cameras_done = devices[: len(cameras)]
    summary["board_check"] = board_checks(collected, board, cameras_done, devices[len(cameras) :])
    summary["world"] = {"frame": world}
    if projectors:
        placed = world_check(collected, board, devices[0], devices[len(cameras)], (rotation, translation))
        summary["world"]["first_view_board"] = placed
    board_warning = board.config.orientation_warning()
    if board_warning is not None:
        summary["warnings"].insert(0, board_warning)
    digest = write_calibration(out, devices, summary, board.config.model_dump(mode="json"), world)
    for device in devices:
        write_atomic(out / f"coverage_{device.name}.png", coverage_png(device))
        write_atomic(out / f"residuals_{device.name}.png", residuals_png(device))
    for device in devices[: len(cameras)]:  # each view with the corners found in it
        c = [name for name, _ in cameras].index(device.name)
        for view in collected:
            if c in view.white:
                found = view.camera.get(c)
                image = view_jpeg(
                    view.white[c], None if found is None else found.points, view_caption(device, view.index)
                )
                write_atomic(out / f"view_{view.index:02d}_{device.name}.jpg", image)
    tracker.report("done", 1.0)
    return CalibrationOutcome(devices, summary, digest, out, len(collected))
