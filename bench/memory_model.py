"""The memory model behind rig.assembly.memory, measured: peak RSS of a whole simulated scan (in a
fresh process each) over a grid of camera and projector resolutions and codecs, a least-squares fit
of bytes per camera pixel and per projector pixel, and the model's estimate beside each measurement
(it must not be below any). Prints one JSON object.

    python bench/memory_model.py                 # the default grid (a few minutes)
    python bench/memory_model.py --quick         # two sizes, one codec
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from rig.assembly.memory import FIXED_BYTES, scan_memory  # noqa: E402
from rig.config import load_config  # noqa: E402

# VmHWM: this process image's peak (ru_maxrss would carry the parent's across fork and exec)
CHILD = """
import json, sys
from rig.assembly import open_rig
from rig.config import load_config
from rig.pipeline.scan import run_scan
config = load_config(sys.argv[1])
with open_rig(config) as rig:
    run_scan(rig, config.scan.codec)
peak_kb = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM:"))
print(json.dumps({"peak": peak_kb * 1024}))
"""


def _resized(device: dict, width: int, height: int) -> None:
    scale = width / device["resolution"][0]
    device["resolution"] = [width, height]
    intrinsics = device["geometry"]["intrinsics"]
    intrinsics.update(fx=intrinsics["fx"] * scale, fy=intrinsics["fy"] * scale, cx=(width - 1) / 2, cy=(height - 1) / 2)


def measure(folder: Path, camera: tuple[int, int], projector: tuple[int, int], codec: str) -> dict:
    data = yaml.safe_load((REPO / "config" / "sim.yaml").read_text())
    _resized(data["cameras"][0], *camera)
    _resized(data["projectors"][0], *projector)
    data.setdefault("scan", {})["codec"] = codec
    path = folder / f"{codec}-{camera[0]}-{projector[0]}.yaml"
    path.write_text(yaml.safe_dump(data))
    run = subprocess.run(
        [sys.executable, "-c", CHILD, str(path)], cwd=REPO, capture_output=True, text=True, check=True, timeout=1800
    )
    peak = json.loads(run.stdout.strip().splitlines()[-1])["peak"]
    estimate = FIXED_BYTES + sum(scan_memory(load_config(path)).values())
    return {
        "codec": codec,
        "camera": list(camera),
        "projector": list(projector),
        "peak_mb": round(peak / 1e6, 1),
        "estimate_mb": round(estimate / 1e6, 1),
        "estimate_over_peak": round(estimate / peak, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    cameras = [(640, 512), (1280, 1024)] if args.quick else [(640, 512), (1280, 1024), (2560, 2048)]
    projectors = [(1024, 768)] if args.quick else [(512, 384), (1024, 768), (2048, 1536)]
    codecs = ["gray"] if args.quick else ["gray", "phase", "rings"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for codec in codecs:
            for camera in cameras:
                for projector in projectors:
                    rows.append(measure(Path(tmp), camera, projector, codec))
    cam = np.array([r["camera"][0] * r["camera"][1] for r in rows], float)
    proj = np.array([r["projector"][0] * r["projector"][1] for r in rows], float)
    peak = np.array([r["peak_mb"] * 1e6 for r in rows])
    design = np.column_stack([np.ones_like(cam), cam, proj])
    fit, *_ = np.linalg.lstsq(design, peak, rcond=None)
    print(
        json.dumps(
            {
                "machine": f"{platform.machine()}, Python {platform.python_version()}",
                "fit": {
                    "fixed_mb": round(fit[0] / 1e6, 1),
                    "bytes_per_camera_pixel": round(fit[1], 1),
                    "bytes_per_projector_pixel": round(fit[2], 1),
                },
                "never_under": bool(min(r["estimate_over_peak"] for r in rows) >= 1.0),
                "rows": rows,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
