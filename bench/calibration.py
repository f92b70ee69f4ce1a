"""Calibration of the default simulated bench against the simulator's geometry; prints one JSON
object: per-device focal and principal-point errors, pose errors, RMS, and the accuracy of a scan
with the estimated calibration against one with the true geometry.

    python bench/calibration.py [--docs]   # --docs: also rewrite the calibration-bench block in docs/
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

from rig.assembly import geometry_model, open_rig
from rig.calibrate.files import load_calibration
from rig.calibrate.session import calibrate
from rig.config import load_config
from rig.evaluate.pairs import evaluate_on_bench
from rig.pipeline.scan import run_scan


def measure() -> dict[str, Any]:
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
    return {
        "benchmark": "calibration",
        "views": outcome.views,
        "seconds": round(seconds, 1),
        "models": {name: d["model"] for name, d in outcome.report["devices"].items()},
        "devices": devices,
        "phase_rms_mm": accuracy,
    }


def table(m: dict[str, Any]) -> str:
    header = [
        "device",
        "lens model",
        "focal length error",
        "principal point error",
        "rotation error",
        "position error",
        "rms",
    ]
    rows = [
        [
            name,
            m["models"][name],
            f"{d['focal_error_pct']:.4f} %",
            f"{d['principal_point_error_px']:.3f} px",
            f"{d['rotation_error_deg']:.4f} deg",
            f"{d['position_error_mm']:.3f} mm",
            f"{d['rms_px']:.3f} px",
        ]
        for name, d in m["devices"].items()
    ]
    rms = m["phase_rms_mm"]
    return (
        markdown_table(header, rows)
        + f"\n\n{m['views']} simulated views, {m['seconds']} s in all. A phase scan with this calibration "
        f"measures {rms['estimated_calibration']:.4f} mm rms against the truth, {rms['true_geometry']:.4f} mm "
        "with the true geometry."
    )


def main() -> None:
    run(__doc__ or "", "calibration-bench", measure, table)


if __name__ == "__main__":
    main()
