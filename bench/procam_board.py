"""Real frames no one here made: kamino410/procam-calibration's five board poses (OpenCV
GrayCodePattern captures, a 1024x768 projector, the authors' calibration_result.xml), reconstructed
by `slrig reconstruct` and measured by what a board must be: flat, and where the camera alone
puts it. Prints one JSON object; with --readme rewrites the procam-board table in README.md.

    python bench/procam_board.py [--readme]      # data: ../shared/data or $SLRIG_TEST_DATA

Per pose: points on the board (inside the hull of its 9x7 detected corners), the rms and p95 of
their distances to a fitted plane, the board's depth from the scan and from the camera alone
(solvePnP on the corners with 75-unit squares, the authors' command), and the seconds the whole
reconstruction took (read, decode, triangulate, write).
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

from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.config import load_config
from rig.service.reconstruct import reconstruct_folder

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


def measure_pose(sample: Path, pose: int, description: Path, scratch: Path) -> dict[str, Any]:
    folder = sample / f"capture_{pose}"
    options = ForeignCalibrationOptions(projector_resolution=(2048, 1536))
    t0 = time.perf_counter()
    path, result = reconstruct_folder(
        folder,
        description,
        sample / "calibration_result.xml",
        scratch / f"pose{pose}",
        f"pose{pose}",
        load_config(),
        options,
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
    camera = read_foreign_calibration(sample / "calibration_result.xml", options).camera
    _, rotation, translation = cv2.solvePnP(squares, corners, camera.K, camera.dist)
    alone = (squares @ cv2.Rodrigues(rotation)[0].T + translation.ravel()).mean(axis=0)
    return {
        "pose": pose,
        "board_pixels": int(board.sum()),
        "board_points": len(points),
        "plane_rms": round(float(np.sqrt(np.mean(distance**2))), 3),
        "plane_p95": round(float(np.percentile(np.abs(distance), 95)), 3),
        "depth_scan": round(float(centre[2]), 1),
        "depth_camera_alone": round(float(alone[2]), 1),
        "depth_difference_pct": round(float(100 * (centre[2] - alone[2]) / alone[2]), 2),
        "points": len(result.cloud),
        "reconstruct_s": round(seconds, 2),
        "scan": path.name,
    }


def measure() -> dict[str, Any]:
    sample = sample_folder()
    with tempfile.TemporaryDirectory() as scratch:
        description = Path(scratch) / "graycode.yaml"
        description.write_text(yaml.safe_dump(DESCRIPTION))
        poses = [measure_pose(sample, pose, description, Path(scratch)) for pose in range(5)]
    return {"benchmark": "procam_board", "description": DESCRIPTION, "poses": poses}


def table(report: dict[str, Any]) -> str:
    header = [
        "pose",
        "board points",
        "plane rms",
        "plane p95",
        "depth (scan)",
        "depth (camera alone)",
        "difference",
        "s",
    ]
    rows = [
        [
            p["pose"],
            p["board_points"],
            p["plane_rms"],
            p["plane_p95"],
            p["depth_scan"],
            p["depth_camera_alone"],
            f"{p['depth_difference_pct']:+.2f} %",
            p["reconstruct_s"],
        ]
        for p in report["poses"]
        if "plane_rms" in p
    ]
    return (
        markdown_table(header, rows)
        + "\n\nMeasured by `python bench/procam_board.py --readme` (lengths in the calibration's unit)."
    )


if __name__ == "__main__":
    run(__doc__ or "", "procam-board", measure, table)
