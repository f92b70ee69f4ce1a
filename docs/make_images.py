"""Make the README's pictures from a scan of the default simulated bench.

python docs/make_images.py
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from rig.config import load_config
from rig.rig import open_rig
from rig.scan import make_codec, run_scan
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


if __name__ == "__main__":
    main()
