"""An adaptive-projection scan's masks kept with its frames (`adaptive_projection/<projector>_<camera>.npz`:
the light each mask let through, (h, w) for the one mask of every pass or (passes, h, w) for a
scan whose passes sent different masks; the pre-scan's map of camera pixels to projector pixels and
which of them had a point of their own), so that reprocessing the frames takes the masks' lean off
and merges the passes as the scan did (rig.pipeline.mask_skew, rig.pipeline.pass_merge)."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import StoreError
from rig.opened_rig import Rig
from rig.pipeline import MaskSkew
from rig.store.atomic import write_atomic

FOLDER = "adaptive_projection"


def write_mask_skews(the_rig: Rig, skews: dict[tuple[int, int], list[MaskSkew]], partial: Path) -> dict[str, str]:
    """Each pair's MaskSkews (one per pass's masks; the same map) as one compressed .npz in the scan
    being written; the manifest's names."""
    (partial / FOLDER).mkdir()
    names = {}
    for (p, c), per_pass in sorted(skews.items()):
        key = the_rig.config.pair_name(p, c)
        skew = per_pass[0]
        light = [one.light.astype(np.float32) for one in per_pass]
        data = io.BytesIO()
        np.savez_compressed(
            data,
            light=light[0] if len(light) == 1 else np.stack(light),
            u=skew.u.astype(np.float32),
            v=skew.v.astype(np.float32),
            own=skew.own,
            bounds=np.array([skew.max_shift_px, skew.fallback_blur_px]),
        )
        names[key] = f"{FOLDER}/{key}.npz"
        write_atomic(partial / names[key], data.getvalue())
    return names


def read_mask_skews(folder: Path, manifest: dict[str, Any]) -> dict[tuple[int, int], list[MaskSkew]]:
    """The masks a stored scan kept, by (projector, camera) index, one per pass's masks; none for a
    scan without them.
    StoreError naming the file where one is unreadable or does not fit the scan's camera."""
    stored = manifest.get("files", {}).get(FOLDER) or {}
    projectors = [p["name"] for p in manifest["config"]["projectors"]]
    cameras = manifest["config"]["cameras"]
    skews = {}
    for p, projector in enumerate(projectors):
        for c, camera in enumerate(cameras):
            name = stored.get(f"{projector}_{camera['name']}")
            if name is not None:
                skews[(p, c)] = _read(folder / name, (camera["resolution"][1], camera["resolution"][0]))
    return skews


def _read(path: Path, shape: tuple[int, int]) -> list[MaskSkew]:
    try:
        with np.load(path, allow_pickle=False) as data:
            light, u, v, own, bounds = (data[k] for k in ("light", "u", "v", "own", "bounds"))
    except (OSError, ValueError, KeyError) as exc:
        raise StoreError(f"{path}: not an adaptive projection's masks ({exc})") from None
    if light.ndim not in (2, 3) or any(a.shape != shape for a in (u, v, own)) or bounds.shape != (2,):
        raise StoreError(f"{path}: the masks do not fit the scan's camera ({shape[1]}x{shape[0]})")
    per_pass = [light] if light.ndim == 2 else list(light)
    return [MaskSkew(one, u, v, own.astype(bool), float(bounds[0]), float(bounds[1])) for one in per_pass]
