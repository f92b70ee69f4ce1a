"""slrig's calibration of real captures no one here made, against the authors' own: kamino410/
procam-calibration's five board poses (OpenCV GrayCodePattern frames, a 1024x768 projector counted
two pixels per code, a 10x8-square board of 75-unit squares) and its calibration_result.xml.
Prints one JSON object; with --docs rewrites the procam-calibration table in the manual (docs/).

    python bench/procam_calibration.py [--docs]      # data: ../shared/data or $SLRIG_TEST_DATA

Rows: the authors' result (OpenCV's full model with k3 for both devices), slrig with its default
lens model (auto) and slrig with the authors' model (full). Columns: focal lengths and centres,
the camera-to-projector rotation's angle from the authors' and its translation, the stereo rms,
and the board as a ruler: each calibration triangulates the same corners (slrig's detection and
decoding) and the squares' mean side is compared with 75, the corners' spread about their plane
reported. A calibration can reproject well and still measure wrong; the ruler shows which does.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run
from procam_board import DESCRIPTION, sample_folder

from rig.calibrate.boards import Board
from rig.calibrate.check import board_check
from rig.calibrate.described import load_described_views, view_folders
from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.calibrate.session import solve_and_write
from rig.config.calibration import BoardConfig
from rig.patterns.spec import PatternSpec

BOARD = BoardConfig(squares=(10, 8), square_mm=75.0)


def _row(label: str, camera: Any, projector: Any, stereo_rms: float, reference: np.ndarray | None) -> dict[str, Any]:
    R_cp = projector.R @ camera.R.T
    T_cp = projector.t - R_cp @ camera.t
    angle = 0.0
    if reference is not None:
        angle = float(np.degrees(np.arccos(np.clip((np.trace(R_cp @ reference.T) - 1) / 2, -1, 1))))
    return {
        "calibration": label,
        "camera_f": [round(float(camera.K[0, 0]), 1), round(float(camera.K[1, 1]), 1)],
        "camera_centre": [round(float(camera.K[0, 2]), 1), round(float(camera.K[1, 2]), 1)],
        "projector_f": [round(float(projector.K[0, 0]), 1), round(float(projector.K[1, 1]), 1)],
        "projector_centre": [round(float(projector.K[0, 2]), 1), round(float(projector.K[1, 2]), 1)],
        "rotation_from_authors_deg": round(angle, 3),
        "translation": [round(float(v), 1) for v in T_cp],
        "stereo_rms_px": round(stereo_rms, 3),
    }


def measure() -> dict[str, Any]:
    sample = sample_folder()
    spec = PatternSpec.model_validate(DESCRIPTION)
    board = Board(BOARD)
    t0 = time.perf_counter()
    views, camera_size = load_described_views(view_folders(sample, "capture_*"), spec, board)
    read_s = time.perf_counter() - t0
    pairs = [(v.camera[0], v.projector[(0, 0)]) for v in views if 0 in v.camera and (0, 0) in v.projector]
    authors = read_foreign_calibration(
        sample / "calibration_result.xml", ForeignCalibrationOptions(projector_resolution=spec.projector.resolution)
    )
    authors_R = authors.projector.R @ authors.camera.R.T
    rows = [_row("authors (full)", authors.camera, authors.projector, 0.8566, None)]
    rows[0]["board"] = board_check(authors.camera, authors.projector, pairs, board)
    rows[0]["models"] = ["full", "full"]
    for model in ("auto", "full"):
        with tempfile.TemporaryDirectory() as out:
            t1 = time.perf_counter()
            cameras, projectors = [("camera0", camera_size)], [("projector0", spec.projector.resolution)]
            outcome = solve_and_write(views, board, cameras, projectors, model, Path(out))
            solve_s = time.perf_counter() - t1
        camera, projector = outcome.devices
        row = _row(f"slrig ({model})", camera, projector, projector.stereo_rms_px or 0.0, authors_R)
        row["board"] = outcome.report["board_check"]["camera0+projector0"]
        row["models"] = [camera.model, projector.model]
        row["std"] = {"camera": camera.std, "projector": projector.std}
        row["held_out_rms_px"] = {"camera": camera.held_out_px, "projector": projector.held_out_px}
        row["solve_s"] = round(solve_s, 2)
        rows.append(row)
    return {"benchmark": "procam_calibration", "read_and_decode_s": round(read_s, 2), "calibrations": rows}


def table(report: dict[str, Any]) -> str:
    header = [
        "calibration",
        "models (camera, projector)",
        "camera f",
        "camera centre",
        "projector f",
        "projector centre",
        "R from authors'",
        "T (camera to projector)",
        "stereo rms px",
        "squares vs 75",
        "worst view",
        "corners off plane",
    ]
    rows = [
        [
            r["calibration"],
            ", ".join(r["models"]),
            " / ".join(f"{v:.1f}" for v in r["camera_f"]),
            ", ".join(f"{v:.1f}" for v in r["camera_centre"]),
            " / ".join(f"{v:.1f}" for v in r["projector_f"]),
            ", ".join(f"{v:.1f}" for v in r["projector_centre"]),
            f"{r['rotation_from_authors_deg']:.2f} deg",
            ", ".join(f"{v:.1f}" for v in r["translation"]),
            r["stereo_rms_px"],
            f"{r['board']['square_error_pct']:+.2f} %",
            f"{r['board']['worst_view_square_error_pct']:+.2f} %",
            r["board"]["plane_rms"],
        ]
        for r in report["calibrations"]
    ]
    return (
        markdown_table(header, rows)
        + "\n\nMeasured by `python bench/procam_calibration.py --docs` (lengths in the board's unit; "
        "projector pixels counted two per code, as the authors' calibration counts them)."
    )


if __name__ == "__main__":
    run(__doc__ or "", "procam-calibration", measure, table)
