"""`slrig doctor --latency`: each projector's display-to-capture latency, measured and stored where
`latency_s: measured` reads it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from rig.opened_rig import LATENCY_FILE, Rig
from rig.store import write_atomic


def measure_latency(rig: Rig, projector: int, camera: int = 0, max_frames: int = 120) -> float:
    """Seconds from show() of a white frame (after black) to the light on the scene, erring long:
    frames are taken as they come until their brightness stops rising, and the first one lit to
    within 3 % of that plateau was exposed entirely after the light arrived; its exposure start,
    less the time of show(), is the latency (at most one frame period too long, never too short)."""
    device, cam = rig.projectors[projector], rig.cameras[camera]
    width, height = device.resolution
    rig.all_dark()
    rig.wait(0.5)
    cam.flush()
    dark = float(cam.capture().image.mean())
    device.show(np.full((height, width), 255, np.uint8))
    shown = rig.clock.now()
    seen: list[tuple[float, float]] = []  # (exposure start, brightness)
    try:
        for _ in range(max_frames):
            frame = cam.capture()
            seen.append((frame.timestamp_s - frame.exposure_us * 1e-6, float(frame.image.mean())))
            if len(seen) >= 3 and seen[-1][1] > dark + 10 and abs(seen[-1][1] - seen[-2][1]) <= 0.01 * seen[-1][1]:
                plateau = seen[-1][1]
                first = next(start for start, level in seen if level >= dark + 0.97 * (plateau - dark))
                return max(0.0, first - shown)
        raise TimeoutError(f"no steady light from {rig.config.projectors[projector].name} within {max_frames} frames")
    finally:
        rig.all_dark()


def store_latencies(folder: Path, values: dict[str, float]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LATENCY_FILE
    existing: dict[str, Any] = json.loads(path.read_text()) if path.is_file() else {}
    existing.update({name: round(v, 4) for name, v in values.items()})
    write_atomic(path, json.dumps(existing, indent=2).encode())
    return path
