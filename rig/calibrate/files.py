"""Calibration files: OpenCV FileStorage YAML (what OpenCV and most tools read) plus JSON (what
slrig reads back), with a content hash that scan manifests record."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from rig.calibrate.solve import DeviceCalibration
from rig.errors import CalibrationError
from rig.geometry import CameraModel
from rig.store import write_atomic

JSON_NAME = "calibration.json"
YAML_NAME = "calibration.yaml"


def _device_dict(d: DeviceCalibration) -> dict[str, Any]:
    return {
        "name": d.name,
        "kind": d.kind,
        "resolution": list(d.resolution),
        "projection": "pinhole",
        "K": np.asarray(d.K).round(10).tolist(),
        "dist": np.asarray(d.dist).round(12).tolist(),
        "R": np.asarray(d.R).round(12).tolist(),
        "t": np.asarray(d.t).round(10).tolist(),
    }


def content_hash(devices: list[dict[str, Any]]) -> str:
    return hashlib.sha256(json.dumps(devices, sort_keys=True).encode()).hexdigest()[:16]


def write_calibration(
    folder: Path, devices: list[DeviceCalibration], report: dict[str, Any], board: dict[str, Any], world: str = "board"
) -> str:
    """Write calibration.json and calibration.yaml into `folder` (each atomically, the YAML first so
    the JSON, which slrig reads, never points at a missing YAML). Returns the content hash."""
    folder.mkdir(parents=True, exist_ok=True)
    params = [_device_dict(d) for d in devices]
    digest = content_hash(params)
    storage = cv2.FileStorage("calibration.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    storage.write("sha256", digest)
    storage.write("world", world)
    for d in devices:
        storage.startWriteStruct(d.name, cv2.FILE_NODE_MAP)
        storage.write("kind", d.kind)
        storage.write("image_width", int(d.resolution[0]))
        storage.write("image_height", int(d.resolution[1]))
        storage.write("camera_matrix", np.asarray(d.K, dtype=np.float64))
        storage.write("distortion_coefficients", np.asarray(d.dist, dtype=np.float64).reshape(1, -1))
        storage.write("rotation_world_to_device", np.asarray(d.R, dtype=np.float64))
        storage.write("translation_world_to_device", np.asarray(d.t, dtype=np.float64).reshape(3, 1))
        storage.write("rms_px", float(d.rms_px))
        storage.endWriteStruct()
    write_atomic(folder / YAML_NAME, storage.releaseAndGetString().encode())
    document = {"sha256": digest, "board": board, "world": world, "devices": params, "report": report}
    write_atomic(folder / JSON_NAME, json.dumps(document, indent=2, allow_nan=False).encode())
    return digest


def calibration_world(path: Path) -> str:
    """The frame a calibration.json (or its folder's) is written in: board (also for files from
    before the choice) or camera."""
    path = path / JSON_NAME if path.is_dir() else path
    try:
        return str(json.loads(path.read_text()).get("world", "board"))
    except (OSError, ValueError, AttributeError) as exc:
        raise CalibrationError(f"calibration file {path}: cannot read: {exc}") from None


def load_calibration(path: Path) -> tuple[dict[str, CameraModel], str]:
    """Device models by name from calibration.json (or its folder), and the content hash."""
    path = path / JSON_NAME if path.is_dir() else path
    try:
        document = json.loads(path.read_text())
        models = {}
        for d in document["devices"]:
            width, height = d["resolution"]
            models[d["name"]] = CameraModel(
                width=int(width),
                height=int(height),
                K=np.array(d["K"]),
                R=np.array(d["R"]),
                t=np.array(d["t"]),
                dist=np.array(d["dist"]),
                projection=d.get("projection", "pinhole"),
            )
        digest = document["sha256"]
        if digest != content_hash(document["devices"]):
            raise CalibrationError(f"calibration file {path}: content does not match its sha256 (edited?)")
        return models, digest
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CalibrationError(f"calibration file {path}: cannot read: {exc}") from None


def own_calibration_json(paths: list[Path]) -> Path | None:
    """slrig's own calibration.json, where `paths` are it alone or a folder holding it."""
    if len(paths) != 1:
        return None
    own = paths[0] / JSON_NAME if paths[0].is_dir() else paths[0]
    return own if own.name == JSON_NAME and (own.is_file() or not paths[0].is_dir()) else None


def load_devices(path: Path, names: tuple[str, ...]) -> tuple[list[CameraModel], str]:
    """The named devices' models from calibration.json, and its hash; CalibrationError naming the
    devices it does not hold."""
    models, digest = load_calibration(path)
    missing = [n for n in names if n not in models]
    if missing:
        raise CalibrationError(
            f"calibration file {path}: has no device {', '.join(missing)} (its: {', '.join(models)})"
        )
    return [models[n] for n in names], digest
