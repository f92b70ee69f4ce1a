"""Real frames no one here made: kamino410/procam-calibration's five board poses (OpenCV
GrayCodePattern captures, a 1024x768 projector), reconstructed by `slrig reconstruct` with the
authors' calibration_result.xml and with slrig's own calibration of the same poses (`slrig
calibrate --images --patterns`), and measured by what a board must be: flat, and where the camera
alone puts it. Prints one JSON object; with --docs rewrites the procam-board table in the manual (docs/).

    python bench/procam_board.py [--docs]      # data: ../shared/data or $SLRIG_TEST_DATA

Per pose: points on the board (inside the hull of its 9x7 detected corners), the rms and p95 of
their distances to a fitted plane, the board's distance from the camera in the scan and from the
camera alone (solvePnP on the corners with 75-unit squares, the authors' command, with that
calibration's camera), and the seconds the whole reconstruction took (read, decode, triangulate,
write).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.calibrate.foreign import ForeignCalibrationOptions
from rig.calibrate.session import calibrate_described
from rig.config import load_config
from rig.service.reconstruct import calibration_models, reconstruct_folder

ROOT = Path(__file__).resolve().parent.parent
# the authors' calibration counts two projector pixels per code (a 2048x1536 image of codes)
DESCRIPTION = {
    "projector": {"resolution": [2048, 1536], "code_step_px": 2},
    "frames": {"files": "graycode_*.png"},
    "gray": {"axes": ["columns", "rows"], "white_black": "last"},
}
SQUARE = 75.0  # the authors' chess_block_size


def sample_folder() -> Path:
    root = Path(os.environ.get("SLRIG_TEST_DATA") or ROOT.parent / "shared" / "data")
    folder = root / "procam-calibration" / "sample_data"
    if not folder.is_dir():
        raise SystemExit(f"no procam-calibration sample data at {folder} (set SLRIG_TEST_DATA)")
    return folder


def measure_pose(
    sample: Path, pose: int, description: Path, calibration: Path, scratch: Path, label: str
) -> dict[str, Any]:
    """One pose reconstructed with one calibration: the board's flatness, and its distance from the
    camera against the camera alone's (solvePnP on the corners, with that calibration's camera)."""
    folder = sample / f"capture_{pose}"
    options = ForeignCalibrationOptions(projector_resolution=(2048, 1536))
    t0 = time.perf_counter()
    path, result = reconstruct_folder(
        folder, description, calibration, scratch / f"{label}{pose}", f"pose{pose}", load_config(), options
    )
    seconds = time.perf_counter() - t0
    white = cv2.imread(str(folder / "graycode_40.png"), cv2.IMREAD_GRAYSCALE)
    found, corners = cv2.findChessboardCorners(white, (9, 7))
    if not found:
        return {"pose": pose, "board_found": False}
    board = np.zeros(white.shape, np.uint8)
    cv2.fillConvexPoly(board, cv2.convexHull(corners.reshape(-1, 2)).astype(np.int32), 1)
    grid = result.pairs[0].grid
    points = grid[(board > 0) & np.isfinite(grid).all(axis=2)]
    centre = points.mean(axis=0)
    distance = (points - centre) @ np.linalg.svd(points - centre, full_matrices=False)[2][2]
    squares = np.zeros((63, 3))
    squares[:, :2] = np.mgrid[0:9, 0:7].T.reshape(-1, 2) * SQUARE
    camera = calibration_models(calibration, options)[0]  # the authors' file or slrig's folder
    _, rotation, translation = cv2.solvePnP(squares, corners, camera.K, camera.dist)
    alone = float(np.linalg.norm((squares @ cv2.Rodrigues(rotation)[0].T + translation.ravel()).mean(axis=0)))
    scanned = float(np.linalg.norm(centre - camera.center))  # the world is the camera's or the first board's
    return {
        "pose": pose,
        "board_pixels": int(board.sum()),
        "board_points": len(points),
        "plane_rms": round(float(np.sqrt(np.mean(distance**2))), 3),
        "plane_p95": round(float(np.percentile(np.abs(distance), 95)), 3),
        "distance_scan": round(scanned, 1),
        "distance_camera_alone": round(alone, 1),
        "distance_difference_pct": round(100 * (scanned - alone) / alone, 2),
        "points": len(result.cloud),
        "reconstruct_s": round(seconds, 2),
        "scan": path.name,
    }


def measure() -> dict[str, Any]:
    sample = sample_folder()
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        description = root / "graycode.yaml"
        description.write_text(yaml.safe_dump(DESCRIPTION))
        config = load_config(write_board_config(root))
        calibrate_described(config, sample, description, root / "slrig-cal", view_glob="capture_*")
        calibrations = {"authors": sample / "calibration_result.xml", "slrig": root / "slrig-cal"}
        poses = [
            {label: measure_pose(sample, pose, description, path, root, label) for label, path in calibrations.items()}
            for pose in range(5)
        ]
    return {"benchmark": "procam_board", "description": DESCRIPTION, "poses": poses}


def write_board_config(folder: Path) -> Path:
    """The default config with the sample's board (10x8 squares of 75 units)."""
    data = yaml.safe_load((ROOT / "config" / "sim.yaml").read_text())
    data.setdefault("calibration", {})["board"] = {"kind": "checker", "squares": [10, 8], "square_mm": SQUARE}
    path = folder / "procam.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def table(report: dict[str, Any]) -> str:
    header = ["pose", "board points", "plane rms", "plane p95", "distance (scan)", "(camera alone)", "difference", "s"]
    rows = []
    for pose in report["poses"]:
        for label, p in pose.items():
            if "plane_rms" not in p:
                continue
            rows.append(
                [
                    f"{p['pose']} ({'the authors' if label == 'authors' else 'slrig'}'s calibration)".replace(
                        "s's", "s'"
                    ),
                    p["board_points"],
                    p["plane_rms"],
                    p["plane_p95"],
                    p["distance_scan"],
                    p["distance_camera_alone"],
                    f"{p['distance_difference_pct']:+.2f} %",
                    p["reconstruct_s"],
                ]
            )
    return (
        markdown_table(header, rows)
        + "\n\nMeasured by `python bench/procam_board.py --docs` (lengths in the calibration's unit; slrig's "
        "calibration made by `slrig calibrate --images --patterns` from the same five poses)."
    )


if __name__ == "__main__":
    run(__doc__ or "", "procam-board", measure, table)
