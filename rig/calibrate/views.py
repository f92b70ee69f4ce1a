"""Calibration views: what each camera saw of the board, with decoded projector coordinates.

A view is captured from the simulated bench (the board placed at a pose the session chooses or the
operator gives) or read from a folder that a real bench, or `--save-views`, wrote:

    <dir>/view_00/<camera>.png                         the board lit by white
    <dir>/view_00/<projector>_<camera>/NNN.png          the calibration patterns, in order
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from rig.calibrate.boards import Board, Detection
from rig.errors import CalibrationError
from rig.opened_rig import Rig
from rig.patterns import Codec, Correspondence, PhaseCodec, PhaseParams
from rig.progress import ProgressCallback, ProgressTracker

HOMOGRAPHY_WINDOW_PX = 15.0  # half-size of the camera window for local homographies
MIN_DECODED_IN_WINDOW = 30
BOARD_PX_PER_MM = 10.0  # the board printed for the simulated bench


@dataclass
class View:
    """One board pose: detections per camera, projector corners per (projector, camera)."""

    index: int
    camera: dict[int, Detection] = field(default_factory=dict)
    label: str = ""  # where it came from (a capture folder's name), for the report
    projector: dict[tuple[int, int], Detection] = field(default_factory=dict)
    white: dict[int, np.ndarray] = field(default_factory=dict)  # detection images, for coverage


def calibration_codec(projector_size: tuple[int, int]) -> Codec:
    """Projector coordinates on the board: phase shift in both directions."""
    return PhaseCodec(projector_size, PhaseParams(directions="both", steps=6, period_px=16))


def default_poses(count: int, centre: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Board poses (rotation board -> world, centre) for a session: first flat at the world origin
    (it defines the world frame), then tilted up to 30 degrees about x and y, turned about z, and
    moved around `centre`, spread so that corners fall all over the images."""
    poses = [(np.eye(3), np.zeros(3))]
    golden = 2.399963  # golden angle: an even spread of tilt directions
    for k in range(1, count):
        tilt = np.radians(12 + 18 * ((k * 0.618) % 1.0))
        direction = k * golden
        axis = np.array([np.cos(direction), np.sin(direction), 0.0])
        turn = np.radians(((k * 37) % 30) - 15)
        rotation = _rotation_about(np.array([0.0, 0.0, 1.0]), turn) @ _rotation_about(axis, tilt)
        offset = np.array([45 * np.cos(3 * direction), 35 * np.sin(2 * direction), 40 * ((k * 0.381) % 1.0)])
        poses.append((rotation, centre + offset))
    return poses


def _rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    rvec = (axis / np.linalg.norm(axis) * angle).reshape(3, 1)
    rotation, _ = cv2.Rodrigues(rvec)
    return rotation


def projector_corners(corr: Correspondence, detection: Detection) -> Detection:
    """Projector coordinates of board corners by local homographies (Moreno and Taubin): the decoded
    pixels around each camera corner, mapped camera -> projector by a robust homography."""
    assert corr.u is not None and corr.v is not None
    valid = corr.valid
    ids, points = [], []
    r = HOMOGRAPHY_WINDOW_PX
    for corner_id, (x, y) in zip(detection.ids, detection.points, strict=True):
        x0, x1 = int(max(0, np.floor(x - r))), int(min(valid.shape[1], np.ceil(x + r) + 1))
        y0, y1 = int(max(0, np.floor(y - r))), int(min(valid.shape[0], np.ceil(y + r) + 1))
        window = valid[y0:y1, x0:x1]
        if window.sum() < MIN_DECODED_IN_WINDOW:
            continue
        rows, cols = np.nonzero(window)
        cam = np.column_stack([cols + x0, rows + y0]).astype(np.float64)
        proj = np.column_stack([corr.u[rows + y0, cols + x0], corr.v[rows + y0, cols + x0]]).astype(np.float64)
        homography, _ = cv2.findHomography(cam - [x, y], proj, cv2.LMEDS)
        if homography is None:
            continue
        mapped = homography @ np.array([0.0, 0.0, 1.0])
        if abs(mapped[2]) < 1e-12:
            continue
        ids.append(corner_id)
        points.append(mapped[:2] / mapped[2])
    return Detection(np.asarray(ids, dtype=int), np.asarray(points, dtype=np.float64).reshape(-1, 2))


def capture_placed_views(
    rig: Rig,
    board: Board,
    poses: list[tuple[np.ndarray, np.ndarray]],
    with_projectors: bool,
    save_to: Path | None = None,
    progress: ProgressCallback | None = None,
) -> list[View]:
    """Place the board at each pose (the rig's hand on the scene) and capture it."""
    if rig.scene is None:
        raise CalibrationError(
            "this rig cannot place the board itself (only the simulated bench can): capture the views "
            "on the bench and give their folder with --images"
        )
    image = board.image(BOARD_PX_PER_MM)
    views = []
    tracker = ProgressTracker(progress)
    for index, (rotation, centre) in enumerate(poses):
        tracker.report("views", index / len(poses), f"view {index + 1} of {len(poses)}")
        axes, origin = board.print_pose(rotation, centre)
        rig.scene.show_board(image, 1.0 / BOARD_PX_PER_MM, axes, origin)
        frames = _capture_view(rig, with_projectors)
        if save_to is not None:
            _save_view(rig, save_to / f"view_{index:02d}", frames)
        views.append(_analyse(rig, board, index, frames))
    rig.all_dark()
    return views


def _capture_view(rig: Rig, with_projectors: bool) -> dict[tuple[int | None, int], list[np.ndarray]]:
    """Frames per (projector or None for the white-lit detection image, camera)."""
    timeout = rig.config.scan.capture_timeout_s
    frames: dict[tuple[int | None, int], list[np.ndarray]] = {}
    white = [np.full((p.resolution[1], p.resolution[0]), 255, np.uint8) for p in rig.projectors]
    rig.all_dark()
    for p, projector in enumerate(rig.projectors):
        projector.show(white[p])
    rig.wait(max((rig.latency_s(p) for p in range(len(rig.projectors))), default=0.0))
    for c, camera in enumerate(rig.cameras):
        camera.flush()  # software sync, as in a scan: frames exposed before the light are dropped
        frames[(None, c)] = [rig.capture(c, timeout).image]
    rig.all_dark()
    if with_projectors:
        for p, projector in enumerate(rig.projectors):
            for pattern in calibration_codec(projector.resolution).iter_patterns():
                projector.show(pattern)
                rig.wait(rig.latency_s(p))
                for c, camera in enumerate(rig.cameras):
                    camera.flush()
                    frames.setdefault((p, c), []).append(rig.capture(c, timeout).image)
            projector.dark()
    return frames


def _analyse(rig: Rig, board: Board, index: int, frames: dict[tuple[int | None, int], list[np.ndarray]]) -> View:
    view = View(index)
    for (p, c), images in frames.items():
        if p is not None:
            continue
        view.white[c] = images[0]
        detection = board.detect(images[0])
        if len(detection):
            view.camera[c] = detection
    for (p, c), images in frames.items():
        if p is None or c not in view.camera:
            continue
        codec = calibration_codec(rig.config.projectors[p].resolution)
        corr = codec.decode(images, rig.config.cameras[c].full_scale)
        corners = projector_corners(corr, view.camera[c])
        if len(corners):
            view.projector[(p, c)] = corners
    return view


def _save_view(rig: Rig, folder: Path, frames: dict[tuple[int | None, int], list[np.ndarray]]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for (p, c), images in frames.items():
        camera = rig.config.cameras[c].name
        if p is None:
            cv2.imwrite(str(folder / f"{camera}.png"), images[0])
            continue
        sub = folder / rig.config.pair_name(p, c)
        sub.mkdir(exist_ok=True)
        for k, image in enumerate(images):
            cv2.imwrite(str(sub / f"{k:03d}.png"), image)


def load_folder_views(
    rig: Rig, board: Board, folder: Path, with_projectors: bool, progress: ProgressCallback | None = None
) -> list[View]:
    """Views from a folder laid out as in this module's docstring."""
    if not folder.is_dir():
        raise CalibrationError(f"--images: no such folder: {folder}")
    view_dirs = sorted(d for d in folder.iterdir() if d.is_dir() and d.name.startswith("view_"))
    if not view_dirs:
        raise CalibrationError(f"--images: {folder} has no view_NN folders")
    views = []
    tracker = ProgressTracker(progress)
    for index, view_dir in enumerate(view_dirs):
        tracker.report("views", index / len(view_dirs), f"view {index + 1} of {len(view_dirs)}")
        frames: dict[tuple[int | None, int], list[np.ndarray]] = {}
        for c, camera in enumerate(rig.config.cameras):
            white = view_dir / f"{camera.name}.png"
            if white.is_file():
                frames[(None, c)] = [_read(white)]
            if not with_projectors:
                continue
            for p, projector in enumerate(rig.config.projectors):
                sub = view_dir / f"{projector.name}_{camera.name}"
                files = sorted(sub.glob("*.png")) if sub.is_dir() else []
                if files:
                    expected = calibration_codec(projector.resolution).frame_count
                    if len(files) != expected:
                        raise CalibrationError(
                            f"--images: {sub} has {len(files)} frames, the calibration patterns are {expected}"
                        )
                    frames[(p, c)] = [_read(f) for f in files]
        views.append(_analyse(rig, board, index, frames))
    return views


def _read(path: Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise CalibrationError(f"--images: cannot read image {path}")
    return image
