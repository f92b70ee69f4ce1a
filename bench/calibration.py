"""Calibration of the default simulated bench against the simulator's geometry; prints one JSON
object: per-device focal and principal-point errors, pose errors, RMS, and the accuracy of a scan
with the estimated calibration against one with the true geometry.

    python bench/calibration.py
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from rig.assembly import geometry_model, open_rig
from rig.calibrate.files import load_calibration
from rig.calibrate.session import calibrate
from rig.config import load_config
from rig.evaluate.pairs import evaluate_on_bench
from rig.pipeline.scan import run_scan


def main() -> None:
    config = load_config()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        start = time.perf_counter()
        with open_rig(config) as rig:
            outcome = calibrate(rig, "rig", folder)
        seconds = time.perf_counter() - start
        models, _ = load_calibration(folder)
        devices = {}
        for d in (*config.cameras, *config.projectors):
            truth, est = geometry_model(d.geometry, d.resolution), models[d.name]
            relative = est.R @ truth.R.T
            angle = np.degrees(np.arccos(np.clip((np.trace(relative) - 1) / 2, -1, 1)))
            devices[d.name] = {
                "focal_error_pct": round(float(100 * abs(est.K[0, 0] / truth.K[0, 0] - 1)), 4),
                "principal_point_error_px": round(float(np.hypot(*(est.K[:2, 2] - truth.K[:2, 2]))), 3),
                "rotation_error_deg": round(float(angle), 4),
                "position_error_mm": round(float(np.linalg.norm(est.center - truth.center)), 4),
                "rms_px": outcome.report["devices"][d.name]["rms_px"],
            }
        accuracy = {}
        for label, file in (("true_geometry", None), ("estimated_calibration", folder)):
            data = config.model_dump(mode="json")
            data["calibration"]["file"] = None if file is None else str(file)
            with open_rig(type(config).model_validate(data)) as rig:
                accuracy[label] = round(float(evaluate_on_bench(rig, run_scan(rig).pairs[0])["rms_mm"]), 4)
    print(
        json.dumps(
            {
                "benchmark": "calibration",
                "views": outcome.views,
                "seconds": round(seconds, 1),
                "devices": devices,
                "phase_rms_mm": accuracy,
            }
        )
    )


if __name__ == "__main__":
    main()
