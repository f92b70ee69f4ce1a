"""A scan directory from frames another system captured: the frames folder read as its pattern
description says, decoded, triangulated with a calibration (slrig's own calibration.json, or
another tool's file), filtered and stored exactly as a scan, the manifest recording where every
input came from and its hash.

The rig of such a scan is one camera and one projector named by the calibration import options,
their models from the calibration; the rest of the rig description (scan filters, output) is the
config's.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from rig.calibrate import (
    ForeignCalibrationOptions,
    check_resolution,
    own_calibration,
    own_calibration_json,
    read_foreign_calibration,
)
from rig.config import RigConfig, config_from_dict
from rig.errors import CalibrationError
from rig.geometry import CameraModel, ray_plane, ray_ray_midpoint
from rig.opened_rig import Rig
from rig.patterns import Correspondence, PatternSpec, decode_described, decoded_warnings
from rig.pipeline import ScanResult, reconstruct_pair
from rig.progress import ProgressCallback, ProgressTracker
from rig.store import FrameSet, frame_files, load_pattern_spec, open_frames, read_image_header, write_scan

CODEC_NAME = "described"
SAMPLES = 4000  # pixels the depth of a code step is measured on


def reconstruct_folder(
    frames_dir: Path,
    patterns: Path | PatternSpec,
    calibration: Path | list[Path],
    target: Path,
    scan_id: str,
    config: RigConfig,
    options: ForeignCalibrationOptions | None = None,
    progress: ProgressCallback | None = None,
    origin: dict[str, Any] | None = None,
) -> tuple[Path, ScanResult]:
    """Reconstruct `frames_dir` into a new scan directory `target`; nothing is written when an
    input is refused (PatternSpecError, FramesError, CalibrationError, DecodeError). `patterns` is
    the description's file, or the description itself (a REST request's, recorded as inline);
    `origin`: more to record of where the reconstruction came from (a batch's input digest)."""
    options = options or ForeignCalibrationOptions()
    spec = patterns if isinstance(patterns, PatternSpec) else load_pattern_spec(patterns)
    ProgressTracker(progress).report("read", 0.05)
    # The calibrated camera's size, required of every frame from its header before it is decoded:
    # frames of another size (or a decompression bomb) cost no memory.
    models = calibration_models(calibration, options)
    camera = models[0]
    first = frame_files(frames_dir, spec.frames, len(spec.roles()), spec.frame_breakdown())[0]
    check_resolution(camera, read_image_header(first).size, "camera", "the frames are", _named(calibration))
    frames = open_frames(frames_dir, spec.frames, len(spec.roles()), (camera.width, camera.height))
    inputs = {
        "frames": str(frames_dir),
        "patterns": "inline" if isinstance(patterns, PatternSpec) else str(patterns),
        "patterns_sha256": _spec_hash(spec) if isinstance(patterns, PatternSpec) else _file_hash(patterns),
        **(origin or {}),
    }
    return reconstruct_frames(frames, spec, calibration, target, scan_id, config, options, inputs, progress, models)


def reconstruct_frames(
    frames: FrameSet,
    spec: PatternSpec,
    calibration: Path | list[Path],
    target: Path,
    scan_id: str,
    config: RigConfig,
    options: ForeignCalibrationOptions,
    inputs: dict[str, Any],
    progress: ProgressCallback | None = None,
    models: tuple[CameraModel, CameraModel, str] | None = None,
) -> tuple[Path, ScanResult]:
    """The in-memory part of reconstruct_folder: frames read, decoded, triangulated, written;
    `inputs` (where the frames and description came from) goes into the manifest; `models`: the
    calibration's camera, projector and hash where the caller has read them already."""
    tracker = ProgressTracker(progress)  # each report is a point where a job can be cancelled
    tracker.report("decode", 0.3)
    height, width = frames.frames[0].shape
    camera, projector, digest = models or calibration_models(calibration, options)
    where = _named(calibration)
    check_resolution(camera, (width, height), "camera", "the frames are", where)
    check_resolution(projector, spec.projector.resolution, "projector", "the pattern description's is", where)
    correspondence = decode_described(frames.frames, spec, frames.full_scale)
    limit = jump_limit(camera, projector, correspondence, spec.projector.code_step_px, config.scan.max_depth_jump_mm)
    rig_config = offline_config(config, options, camera, projector, frames.full_scale, limit)
    the_rig = Rig(rig_config, [], [], [projector], [camera], calibration_sha256=digest)
    tracker.report("triangulate", 0.6)
    pair = reconstruct_pair(the_rig, 0, 0, correspondence, source=0)
    tracker.report("store", 0.9)
    result = ScanResult(
        CODEC_NAME,
        spec.model_dump(mode="json"),
        [pair],
        pair.points,
        frames_projected=len(frames.frames),
        bytes_captured=sum(f.nbytes for f in frames.frames),
        warnings=decoded_warnings(spec, correspondence),
    )
    origin = {
        "reconstructed": {
            **inputs,
            "frames_sha256": frames.sha256,  # after the decoding: the frames are read by then
            "calibration": _named(calibration),
            "calibration_sha256": digest,
            "calibration_options": options.model_dump(mode="json"),
            "warnings": result.warnings,
        }
    }
    return write_scan(the_rig, result, target, scan_id, None, origin), result


def calibration_models(
    path: Path | list[Path], options: ForeignCalibrationOptions
) -> tuple[CameraModel, CameraModel, str]:
    """The camera and projector of slrig's calibration.json (by the options' device names) or of
    another tool's file (or files, read together), and the calibration's hash."""
    paths = path if isinstance(path, list) else [path]
    own = own_calibration_json(paths)
    if own is not None:
        camera, projector, digest, _ = own_calibration(own, options)
        return camera, projector, digest
    found = read_foreign_calibration(paths, options)
    digest = (
        _file_hash(paths[0])
        if len(paths) == 1
        else hashlib.sha256("".join(map(_file_hash, paths)).encode()).hexdigest()
    )
    assert found.projector is not None  # a camera alone is refused unless single_device is asked
    return found.camera, found.projector, digest[:16]


def _named(calibration: Path | list[Path]) -> str:
    """The calibration's file, or its files read together, for messages and the manifest."""
    return " + ".join(str(p) for p in calibration) if isinstance(calibration, list) else str(calibration)


def jump_limit(
    camera: CameraModel, projector: CameraModel, found: Correspondence, step_px: int, configured: float | None
) -> float | None:
    """The depth-jump filter's limit for these frames: the config's, or three times the depth one
    code step makes here if that is more (a Gray code's depth moves in steps of a code; a rig far
    from its object, or with a short baseline, steps by more than the bench's 2 mm). Measured on
    up to SAMPLES decoded pixels, triangulated at their code and one step on."""
    rows, cols = np.nonzero(found.valid)
    if configured is None or len(rows) == 0:
        return configured
    pick = np.random.default_rng(0).choice(len(rows), min(SAMPLES, len(rows)), replace=False)
    rows, cols = rows[pick], cols[pick]
    origins, directions = camera.rays(np.column_stack([cols, rows]).astype(np.float64))
    depth = [_depth(projector, found, rows, cols, origins, directions, shift) @ camera.axis for shift in (0.0, step_px)]
    step = np.abs(depth[1] - depth[0])
    step = step[np.isfinite(step)]
    return configured if len(step) == 0 else max(configured, 3.0 * float(np.median(step)))


def _depth(
    projector: CameraModel,
    found: Correspondence,
    rows: np.ndarray,
    cols: np.ndarray,
    origins: np.ndarray,
    directions: np.ndarray,
    shift: float,
) -> np.ndarray:
    """Points of the sampled pixels with their codes moved by `shift`: ray-ray where both
    coordinates are coded, else the camera ray on the (undistorted) projector column or row."""
    if found.u is not None and found.v is not None:
        coded = np.column_stack([found.u[rows, cols], found.v[rows, cols]]).astype(np.float64) + shift
        return ray_ray_midpoint(origins, directions, *projector.rays(coded))[0]
    k = projector.K
    if found.u is not None:
        planes = projector.plane_through_column((found.u[rows, cols] + shift - k[0, 2]) / k[0, 0])
    else:
        assert found.v is not None
        planes = projector.plane_through_row((found.v[rows, cols] + shift - k[1, 2]) / k[1, 1])
    points, ok = ray_plane(origins, directions, *planes)
    return np.where(ok[:, None], points, np.nan)


def offline_config(
    config: RigConfig,
    options: ForeignCalibrationOptions,
    camera: CameraModel,
    projector: CameraModel,
    full_scale: int,
    jump_limit_mm: float | None,
) -> RigConfig:
    """`config` with one camera and one projector, as calibrated (the geometry a config can hold;
    the exact models travel beside it), and the depth-jump limit for these frames."""
    data: dict[str, Any] = config.model_dump(mode="json")
    data["scan"] = {**data["scan"], "max_depth_jump_mm": None if jump_limit_mm is None else min(jump_limit_mm, 1000.0)}
    data["projectors"] = [
        {"name": options.projector, "resolution": [projector.width, projector.height], "geometry": _geometry(projector)}
    ]
    data["cameras"] = [
        {
            "name": options.camera,
            "resolution": [camera.width, camera.height],
            "geometry": _geometry(camera),
            "bit_depth": 16 if full_scale > 255 else 8,
        }
    ]
    data["calibration"] = {**data["calibration"], "file": None}
    return config_from_dict(data, "reconstruction")


def _geometry(model: CameraModel) -> dict[str, Any]:
    centre = model.center
    return {
        "intrinsics": {
            "fx": model.K[0, 0],
            "fy": model.K[1, 1],
            "cx": model.K[0, 2],
            "cy": model.K[1, 2],
            "skew": model.K[0, 1],
        },
        "distortion": [float(np.clip(d, -10.0, 10.0)) for d in model.dist],
        "pose": {
            "position_mm": centre.tolist(),
            "look_at_mm": (centre + 100.0 * model.axis).tolist(),
            "up": (-model.R[1]).tolist(),
        },
    }


def _file_hash(path: Path) -> str:
    """A file's SHA-256; a folder's (3DUNDERWORLD's text files): of its files' names and hashes."""
    try:
        if path.is_dir():
            files = sorted(f for f in path.iterdir() if f.is_file())
            return hashlib.sha256("".join(f"{f.name}:{_file_hash(f)}" for f in files).encode()).hexdigest()
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot be read ({exc.strerror})") from None


def _spec_hash(spec: PatternSpec) -> str:
    return hashlib.sha256(json.dumps(spec.model_dump(mode="json"), sort_keys=True).encode()).hexdigest()
