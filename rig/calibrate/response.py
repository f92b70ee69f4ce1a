"""Projector response (gamma) calibration, the most frequent cause of wavy clouds in the field.

Every projector shows uniform grey levels in turn; the cameras measure how much light each level
gives, normalised between black and white per pixel (which removes albedo, fall-off and the
projector's black level) and averaged over the lit pixels. The result is the response curve
r(level) in [0, 1]; codecs then send r^-1(desired) so that the emitted light is what they meant.
It assumes linear cameras (the usual for machine-vision sensors; a camera response would be
calibrated the same way against a known light).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import CalibrationError
from rig.opened_rig import Rig
from rig.store import write_atomic

RESPONSE_NAME = "response.json"
LEVELS = np.linspace(0, 255, 18).round().astype(int)  # 0, 15, 30, ... 255
MIN_RANGE = 0.15  # a pixel is used where white - black exceeds this fraction of full scale ...
MAX_WHITE = 0.95  # ... and white does not saturate


def measure_response(rig: Rig, projector: int) -> tuple[np.ndarray, np.ndarray]:
    """Levels and the measured response r(level) of one projector, median over lit camera pixels."""
    device = rig.projectors[projector]
    width, height = device.resolution
    timeout = rig.config.scan.capture_timeout_s
    rig.all_dark()
    captures: list[list[np.ndarray]] = [[] for _ in rig.cameras]
    try:
        for level in LEVELS:
            device.show(np.full((height, width), level, np.uint8))
            rig.wait(rig.latency_s(projector))
            for c, camera in enumerate(rig.cameras):
                camera.flush()
                captures[c].append(rig.capture(c, timeout).image.astype(np.float32))
    finally:
        rig.all_dark()
    samples = []
    for c, frames in enumerate(captures):
        full = float(rig.config.cameras[c].full_scale)
        stack = np.stack([f if f.ndim == 2 else f.mean(axis=2) for f in frames]) / full
        black, white = stack[0], stack[-1]
        usable = (white - black > MIN_RANGE) & (white < MAX_WHITE)
        if usable.sum() > 100:
            samples.append((stack[:, usable] - black[usable]) / (white[usable] - black[usable]))
    if not samples:
        raise CalibrationError(
            f"{rig.config.projectors[projector].name}: no camera sees enough of its light "
            "(need pixels where white is bright but not saturated)"
        )
    response = np.median(np.concatenate(samples, axis=1), axis=1)
    response = np.maximum.accumulate(np.clip(response, 0.0, 1.0))  # monotone by construction
    return LEVELS.astype(float), response


def fit_gamma(levels: np.ndarray, response: np.ndarray) -> float:
    """The gamma of r = (level / 255) ** gamma that fits best (least squares), for the report."""
    candidates = np.linspace(0.3, 4.0, 3701)
    x = levels / 255.0
    errors = [np.sum((x**g - response) ** 2) for g in candidates]
    return float(candidates[int(np.argmin(errors))])


def inverse_lut(levels: np.ndarray, response: np.ndarray) -> np.ndarray:
    """uint8 LUT: the level to send for each desired output 0..255 (linear light)."""
    desired = np.arange(256) / 255.0
    strictly = response + np.arange(len(response)) * 1e-9  # np.interp needs increasing x
    return np.clip(np.rint(np.interp(desired, strictly, levels)), 0, 255).astype(np.uint8)


def calibrate_response(rig: Rig, out: Path) -> dict[str, Any]:
    """Measure every projector's response and write response.json into `out`."""
    document: dict[str, Any] = {"projectors": {}}
    for p, config in enumerate(rig.config.projectors):
        levels, response = measure_response(rig, p)
        document["projectors"][config.name] = {
            "levels": levels.astype(int).tolist(),
            "response": np.round(response, 6).tolist(),
            "gamma": round(fit_gamma(levels, response), 4),
        }
    document["sha256"] = hashlib.sha256(json.dumps(document["projectors"], sort_keys=True).encode()).hexdigest()[:16]
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / RESPONSE_NAME, json.dumps(document, indent=2, allow_nan=False).encode())
    return document


def load_response_luts(folder: Path) -> tuple[dict[str, np.ndarray], str] | None:
    """Inverse-response LUTs by projector name from response.json in `folder`, if there is one."""
    path = folder / RESPONSE_NAME
    if not path.is_file():
        return None
    try:
        document = json.loads(path.read_text())
        luts = {
            name: inverse_lut(np.array(p["levels"], float), np.array(p["response"], float))
            for name, p in document["projectors"].items()
        }
        return luts, str(document["sha256"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CalibrationError(f"response file {path}: cannot read: {exc}") from None
