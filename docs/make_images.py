"""Make the README's pictures from a scan of the default simulated bench.

python docs/make_images.py
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np

from rig.assembly import open_rig
from rig.config import REPO_CONFIG_DIR, load_config
from rig.geometry import CameraModel, look_at_rotation
from rig.pipeline.capture import CUE
from rig.pipeline.scan import make_codec, run_scan
from rig.store.images import preview_png

OUT = Path(__file__).resolve().parent / "images"


def _save(name: str, image: np.ndarray, width: int = 640) -> None:
    scale = width / image.shape[1]
    small = cv2.resize(image, (width, round(image.shape[0] * scale)), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(OUT / name), small)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    shown = {"phase": 4, "gray": 4, "rings": 2}  # a fringe, a Gray-code bit, the ring edge pattern
    for codec_name in ("phase", "gray", "rings"):
        config = load_config().with_codec(codec_name)
        with open_rig(config) as rig:
            codec = make_codec(rig, 0)
            patterns = codec.patterns()
            rig.projectors[0].show(patterns[shown[codec_name]])
            frame = rig.cameras[0].capture().image
            _save(f"frame_{codec_name}.png", frame)
            result = run_scan(rig)
            preview = cv2.imdecode(
                np.frombuffer(preview_png(result.cloud, rig.camera_models[0]), np.uint8), cv2.IMREAD_COLOR
            )
            _save(f"preview_{codec_name}.png", preview)
    _multi()


def _multi() -> None:
    """sim-multi: what the left camera sees with both projectors lit, the overlap the intensity cue
    finds (orange) and the merged cloud coloured by the pair each point was kept from."""
    with open_rig(load_config(REPO_CONFIG_DIR / "sim-multi.yaml")) as rig:
        result = run_scan(rig, keep_frames=True)
        both = result.frames[(CUE, 0)][-1]
        view = cv2.cvtColor(both, cv2.COLOR_GRAY2BGR) if both.ndim == 2 else both.copy()
        view[result.overlap[0]] = (0.5 * view[result.overlap[0]] + (0, 80, 128)).astype(np.uint8)
        _save("multi_overlap.png", view)
        palette = np.array([[230, 120, 40], [40, 160, 230], [60, 200, 90], [200, 60, 200]], np.uint8)
        tinted = dataclasses.replace(result.cloud, colors=palette[result.cloud.source % 4])
        above = look_at_rotation(np.array([0.0, -350.0, 600.0]), np.array([0.0, 0.0, 30.0]), np.array([0.0, 1.0, 0.0]))
        camera = CameraModel(
            1024,
            768,
            np.array([[2000.0, 0, 511.5], [0, 2000.0, 383.5], [0, 0, 1]]),
            above,
            -above @ [0.0, -350.0, 600.0],
        )
        png = preview_png(tinted, camera, own_colors=True)
        preview = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
        _save("multi_merged.png", preview)


if __name__ == "__main__":
    main()
