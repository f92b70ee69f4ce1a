"""The scan directory: cloud.ply, depth_<camera>.png, preview.png, frames/, manifest.json.

Written into `<id>.partial/`, manifest last, then renamed into place, so a directory without the
`.partial` suffix is always complete.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import json
import platform
import secrets
import shutil
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

import rig
from rig.errors import StoreError
from rig.geometry import CameraModel
from rig.opened_rig import Rig
from rig.pipeline import CUE, PairResult, ScanResult, ring_bands, ring_lit, surface_holes
from rig.store.atomic import fsync_dir, publish_folder, write_atomic
from rig.store.images import depth_image_png, grid_depth, mask_png, point_depth, preview_png, rgb_png
from rig.store.mask_files import FOLDER as MASKS
from rig.store.mask_files import write_mask_skews
from rig.store.ply import mesh_ply_chunks, ply_chunks

DESCRIPTION_NAME = "patterns.yaml"  # beside kept frames: what they show, for `slrig reconstruct`


def new_scan_id() -> str:
    now = dt.datetime.now(dt.UTC)
    return now.strftime("%Y%m%d-%H%M%S-") + secrets.token_hex(3)


def calibration_hashes(the_rig: Rig) -> dict[str, str]:
    """The calibration file's hash for every device when reconstruction used one, else a hash of
    each device's geometry in the config."""
    if the_rig.calibration_sha256 is not None:
        return {d.name: the_rig.calibration_sha256 for d in (*the_rig.config.projectors, *the_rig.config.cameras)}
    out = {}
    for device in (*the_rig.config.projectors, *the_rig.config.cameras):
        blob = json.dumps(device.geometry.model_dump(mode="json"), sort_keys=True).encode()
        out[device.name] = hashlib.sha256(blob).hexdigest()[:16]
    return out


def _software() -> dict[str, str]:
    return {
        "slrig": rig.__version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
    }


def build_manifest(
    the_rig: Rig,
    result: ScanResult,
    scan_id: str,
    files: dict[str, Any],
    metrics: dict[str, Any] | None = None,
    origin: dict[str, Any] | None = None,
) -> dict[str, Any]:
    config = the_rig.config
    return {
        "scan_id": scan_id,
        "origin": origin or {"captured": True},
        "status": "done",
        "created_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "software": _software(),
        "codec": {"name": result.codec, "params": result.codec_params},
        "devices": {
            "projectors": [
                {"name": p.name, "driver": p.driver, "resolution": list(p.resolution)} for p in config.projectors
            ],
            "cameras": [
                {
                    "name": c.name,
                    "driver": c.driver,
                    "resolution": list(c.resolution),
                    "bit_depth": c.bit_depth,
                    "exposure_us": _exposure_us(the_rig, i, c.exposure_us),
                }
                for i, c in enumerate(config.cameras)
            ],
        },
        "calibration_sha256": calibration_hashes(the_rig),
        "response_sha256": the_rig.response_sha256,
        "economy": {
            "frames_projected": result.frames_projected,
            "frames_captured": result.frames_projected * len(config.cameras),
            "bytes_captured": result.bytes_captured,
            "points": len(result.cloud),
        },
        "pairs": [
            {
                "projector": config.projectors[p.projector].name,
                "camera": config.cameras[p.camera].name,
                "points": len(p.points),
                "counts": p.counts,
                **({"ring_coverage": p.ring_coverage} if p.ring_coverage is not None else {}),
            }
            for p in result.pairs
        ],
        **({"surface": _surface_summary(the_rig, result)} if result.mesh is not None else {}),
        **({"adaptive": result.adaptive} if result.adaptive is not None else {}),
        **({"exposure": result.exposure} if result.exposure is not None else {}),
        "timings_ms": {k: round(v, 1) for k, v in result.timings_ms.items()},
        "merge": result.merge,
        "metrics": metrics or {},
        "files": files,
        "config": config.model_dump(mode="json"),
    }


def _surface_summary(the_rig: Rig, result: ScanResult) -> dict[str, Any]:
    assert result.mesh is not None
    config = the_rig.config.scan.surface
    holes = {}
    for pair in result.pairs:
        bands = ring_bands(pair.correspondence)
        if pair.surface is not None and bands is not None:
            name = f"{the_rig.config.projectors[pair.projector].name}/{the_rig.config.cameras[pair.camera].name}"
            lit = ring_lit(the_rig, pair.correspondence)
            holes[name] = surface_holes(pair.surface, bands, lit, the_rig.camera_models[pair.camera])
    return {
        "interpolant": config.interpolant,
        "mesh_vertices": len(result.mesh.vertices),
        "mesh_faces": len(result.mesh.faces),
        "pixels": sum(int(p.surface.valid.sum()) for p in result.pairs if p.surface is not None),
        "holes": holes,
    }


def _pair_depth(pair: PairResult, camera: CameraModel, surface: bool) -> np.ndarray | None:
    """Camera-frame depth (H, W) float32 of a pair's points (with `surface`, of the surface between
    its rings), NaN where none. A fast-path pair's points are projected a block at a time, without
    its organised grid."""
    if surface:
        return None if pair.surface is None else grid_depth(pair.surface.grid, camera)
    if pair.stored_grid is not None:
        return grid_depth(pair.stored_grid, camera)
    return point_depth(pair.points.points, pair.points.pixel, pair.correspondence.valid.shape, camera)


def _depth_image(result: ScanResult, camera: CameraModel, index: int, surface: bool = False) -> np.ndarray | None:
    """Depth of a camera's points (see _pair_depth), filled from each projector in turn (None: no
    pair has that camera)."""
    depth: np.ndarray | None = None
    for pair in result.pairs:
        if pair.camera != index:
            continue
        found = _pair_depth(pair, camera, surface)
        if found is None:
            continue
        if depth is None:
            depth = found
        else:
            missing = np.isnan(depth)
            depth[missing] = found[missing]
    return depth


def _write_depth(path: Path, depth: np.ndarray | None) -> bool:
    """Write a depth image (None: scan.merge.pairs left its camera out); the image is let go on
    return, before the next one or the preview is made."""
    if depth is None:
        return False
    write_atomic(path, depth_image_png(depth))
    return True


TRUTH_ERRORS = "truth_error_mm.npy"  # float32 per cloud point, in cloud.ply's order


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    return buffer.getvalue()


def _exposure_us(the_rig: Rig, camera: int, configured: float) -> float:
    """The exposure the camera had (an operator may have set it while aiming), else the config's."""
    devices = the_rig.cameras
    return devices[camera].exposure_us if camera < len(devices) else configured


def write_scan(
    the_rig: Rig,
    result: ScanResult,
    target: Path,
    scan_id: str,
    metrics: dict[str, Any] | None = None,
    origin: dict[str, Any] | None = None,
    errors: np.ndarray | None = None,
) -> Path:
    """Write the scan directory at `target` (which must not exist) and return it. `errors`: each
    cloud point's distance to the true surface (simulated rigs), kept as TRUTH_ERRORS for viewers."""
    target = Path(target)
    if target.exists():
        raise StoreError(f"output directory already exists, not overwriting: {target}")
    partial = target.with_name(target.name + ".partial")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        if partial.exists():
            shutil.rmtree(partial)  # left by an interrupted write of this same id: incomplete
        partial.mkdir()
        files: dict[str, Any] = {"cloud": "cloud.ply", "preview": "preview.png", "depth": {}}
        write_atomic(partial / "cloud.ply", ply_chunks(result.cloud, comment=f"slrig scan {scan_id}"))
        for c, camera in enumerate(the_rig.config.cameras):
            name = f"depth_{camera.name}.png"
            if _write_depth(partial / name, _depth_image(result, the_rig.camera_models[c], c)):
                files["depth"][camera.name] = name
        write_atomic(partial / "preview.png", preview_png(result.cloud, the_rig.camera_models[0]))
        if result.mesh is not None:
            files["surface"] = _write_surface(the_rig, result, partial, scan_id)
        for c, mask in result.overlap.items():
            name = f"overlap_{the_rig.config.cameras[c].name}.png"
            write_atomic(partial / name, mask_png(mask))
            files.setdefault("overlap", {})[the_rig.config.cameras[c].name] = name
        if result.frames:
            files["frames"] = _write_frames(the_rig, result, partial)
            if result.mask_skews:  # reprocessing takes the masks' lean off as the scan did
                files[MASKS] = write_mask_skews(the_rig, result.mask_skews, partial)
        for name, image in result.images.items():  # e.g. an adaptive scan's pilot as the projector saw it
            write_atomic(partial / f"{name}.png", rgb_png(image))
            files.setdefault("images", {})[name] = f"{name}.png"
        if errors is not None and len(errors) == len(result.cloud):
            write_atomic(partial / TRUTH_ERRORS, _npy(errors.astype("<f4")))
            files["truth_errors"] = TRUTH_ERRORS
        manifest = build_manifest(the_rig, result, scan_id, files, metrics, origin)
        write_atomic(partial / "manifest.json", json.dumps(manifest, indent=2, allow_nan=False).encode())
        publish_folder(partial, target)
    except FileExistsError:
        raise StoreError(f"output directory already exists, not overwriting: {target}") from None
    except OSError as exc:
        shutil.rmtree(partial, ignore_errors=True)  # a full disk gets its space back at once
        raise StoreError(f"cannot write scan to {target}: {exc}") from exc
    return target


def _write_surface(the_rig: Rig, result: ScanResult, partial: Path, scan_id: str) -> dict[str, Any]:
    """mesh.ply and, per camera, the depth map of the surface interpolated between the rings."""
    assert result.mesh is not None
    write_atomic(partial / "mesh.ply", mesh_ply_chunks(result.mesh, comment=f"slrig surface {scan_id}"))
    out: dict[str, Any] = {"mesh": "mesh.ply", "depth": {}}
    for c, camera in enumerate(the_rig.config.cameras):
        name = f"surface_depth_{camera.name}.png"
        if _write_depth(partial / name, _depth_image(result, the_rig.camera_models[c], c, surface=True)):
            out["depth"][camera.name] = name
    return out


def _write_frames(the_rig: Rig, result: ScanResult, partial: Path) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for (p, c), images in sorted(result.frames.items()):
        camera = the_rig.config.cameras[c].name
        key = f"overlap-cue_{camera}" if p < 0 else the_rig.config.pair_name(p, c)
        folder = partial / "frames" / key
        folder.mkdir(parents=True)
        fsync_dir(folder.parent)  # the new entry in frames/ (and frames/ in the scan) must survive
        names = []
        for k, image in enumerate(images):
            _, buf = cv2.imencode(".png", image)
            name = f"frames/{key}/{k:03d}.png"
            write_atomic(partial / name, buf.tobytes())
            names.append(name)
        if p in result.descriptions:  # `slrig reconstruct` reads the folder as it reads others'
            description = {**result.descriptions[p], "frames": {"files": "*.png", "grey": "luminance"}}
            write_atomic(folder / DESCRIPTION_NAME, yaml.safe_dump(description, sort_keys=False).encode())
        out[key] = names
    if out:
        fsync_dir(partial / "frames")
    return out


def read_scan_frames(folder: Path) -> tuple[dict[str, Any], dict[tuple[int, int], list[np.ndarray]]]:
    """The manifest of a stored scan and its raw frames by (projector, camera) index."""
    manifest = json.loads((folder / "manifest.json").read_text())
    stored = manifest["files"].get("frames")
    if not stored:
        raise StoreError(f"scan {manifest['scan_id']} kept no frames (scan with save_frames / keep_frames)")
    projectors = [p["name"] for p in manifest["config"]["projectors"]]
    cameras = [c["name"] for c in manifest["config"]["cameras"]]
    frames: dict[tuple[int, int], list[np.ndarray]] = {}
    keys = [(p, c, f"{name}_{camera}") for p, name in enumerate(projectors) for c, camera in enumerate(cameras)]
    keys += [(CUE, c, f"overlap-cue_{camera}") for c, camera in enumerate(cameras)]
    for p, c, key in keys:
        if key not in stored:
            continue
        images = [cv2.imread(str(folder / name), cv2.IMREAD_UNCHANGED) for name in stored[key]]
        if any(image is None for image in images):
            raise StoreError(f"scan {manifest['scan_id']}: a frame of {key} cannot be read")
        frames[(p, c)] = images
    return manifest, frames
