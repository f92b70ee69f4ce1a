"""slrig's Gray decoder side by side with OpenCV contrib's structured_light.GrayCodePattern, on the
same frames in the same run; prints one JSON object.

OpenCV contrib's wheel conflicts with the headless one slrig installs, so it goes into a throw-away
venv (made in a temporary folder, removed afterwards) and runs there as a worker. The frames are
OpenCV's own patterns (GrayCodePattern.generate() plus its white and black images), shown on the
default simulated bench (1024x768 projector) and seen by its camera and a second camera beside it
(decode() matches two cameras). Reported, per camera:

- OpenCV `decode()` (both cameras, median of 3) divided by two, and `getProjPixel` called for
  every pixel of one camera (once), against slrig's Gray stream decoding the same frames (median of 7);
- coverage: pixels each decodes (OpenCV: inside its shadow mask with getProjPixel succeeding);
- agreement: of the pixels both decode, those with the same projector column and row.

    python bench/peer_opencv.py            # JSON
    python bench/peer_opencv.py --docs   # also rewrite the peer table in the manual (docs/)
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, replace_block

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.patterns import codec_class
from rig.patterns.stream import decode_streamed
from rig.pipeline.capture import capture
from rig.progress import ProgressTracker

PEER = "opencv-contrib-python-headless"
WHITE_THRESHOLD = 5  # counts: |pattern - inverse| a bit needs (slrig's default 0.02 of 255)
BLACK_THRESHOLD = 8  # counts: white - black a pixel needs (slrig's default 0.03 of 255)

_WORKER = textwrap.dedent(
    """
    import json, statistics, sys, time
    import cv2, numpy as np
    mode, path = sys.argv[1], sys.argv[2]
    pattern = cv2.structured_light.GrayCodePattern.create(1024, 768)
    pattern.setWhiteThreshold(int(sys.argv[3]))
    pattern.setBlackThreshold(int(sys.argv[4]))
    if mode == "patterns":
        ok, images = pattern.generate()
        black, white = pattern.getImagesForShadowMasks(np.zeros((768, 1024), np.uint8), np.zeros((768, 1024), np.uint8))
        np.savez(path, white=white, black=black, patterns=np.stack(images))
        sys.exit(0)
    data = np.load(path)
    cams = [[data[f"c{c}_{k}"] for k in range(int(data["count"]))] for c in (0, 1)]
    whites, blacks = [data["w0"], data["w1"]], [data["b0"], data["b1"]]
    times = []
    for _ in range(3):
        t = time.perf_counter()
        ok, disparity = pattern.decode(cams, None, blacks, whites, cv2.structured_light.DECODE_3D_UNDERWORLD)
        times.append(time.perf_counter() - t)
    h, w = whites[0].shape
    u = np.full((h, w), -1, np.int32); v = np.full((h, w), -1, np.int32)
    lit = (whites[0].astype(np.int32) - blacks[0]) > int(sys.argv[4])
    t = time.perf_counter()
    for y in range(h):
        for x in range(w):
            if lit[y, x]:
                failed, pixel = pattern.getProjPixel(cams[0], x, y)
                if not failed:
                    u[y, x], v[y, x] = pixel
    per_pixel = time.perf_counter() - t
    np.savez(path + ".out.npz", u=u, v=v)
    print(json.dumps({"decode_s": statistics.median(times), "decode_ok": bool(ok), "get_proj_pixel_s": per_pixel,
                      "opencv": cv2.__version__}))
    """
)


def two_camera_config() -> Any:
    """The default bench with a second camera 160 mm beside the first (decode() matches two)."""
    data = load_config().model_dump(mode="json")
    second = json.loads(json.dumps(data["cameras"][0]))
    second["name"] = "camera1"
    second["geometry"]["pose"]["position_mm"] = [-100.0, 160.0, 600.0]
    data["cameras"].append(second)
    data["scan"]["codec"] = "gray"
    data["scan"]["gray"] = {"directions": "both"}
    return config_from_dict(data, "peer-opencv")


class _Shown:
    """A codec-shaped list of patterns for capture(): OpenCV's images, white and black first."""

    name = "opencv-gray"

    def __init__(self, images: list[np.ndarray]) -> None:
        self.images = images
        self.frame_count = len(images)

    def patterns(self) -> list[np.ndarray]:
        return self.images

    def iter_patterns(self) -> Iterator[np.ndarray]:
        return iter(self.images)


def peer(python: Path, work: Path) -> dict[str, Any]:
    patterns_file = work / "patterns.npz"
    args = [str(WHITE_THRESHOLD), str(BLACK_THRESHOLD)]
    subprocess.run([str(python), "-c", _WORKER, "patterns", str(patterns_file), *args], check=True, timeout=600)
    generated = np.load(patterns_file)
    shown = [generated["white"], generated["black"], *generated["patterns"]]
    config = two_camera_config()
    with open_rig(config) as rig:
        frames = capture(rig, [_Shown(shown)], ProgressTracker(None))  # type: ignore[list-item]
    cams = [frames[(0, c)] for c in (0, 1)]
    frames_file = work / "frames.npz"
    arrays = {f"c{c}_{k}": image for c in (0, 1) for k, image in enumerate(cams[c][2:])}
    arrays |= {
        "w0": cams[0][0],
        "b0": cams[0][1],
        "w1": cams[1][0],
        "b1": cams[1][1],
        "count": np.array(len(shown) - 2),
    }
    np.savez(frames_file, **arrays)
    worker = subprocess.run(
        [str(python), "-c", _WORKER, "decode", str(frames_file), *args],
        check=True,
        capture_output=True,
        text=True,
        timeout=3600,
    )
    theirs = json.loads(worker.stdout.strip().splitlines()[-1])
    found = np.load(str(frames_file) + ".out.npz")
    codec = codec_class("gray")((1024, 768), config.scan.gray)
    same_patterns = all(np.array_equal(a, b) for a, b in zip(codec.patterns(), shown, strict=True))
    ours, corr = slrig_decode(codec, cams[0])
    both = corr.valid & (found["u"] >= 0)
    agree = both & (corr.u == found["u"]) & (corr.v == found["v"])
    pixels = corr.valid.size
    decode_per_camera = theirs["decode_s"] / 2
    return {
        "benchmark": "peer_opencv",
        "opencv_contrib": theirs["opencv"],
        "frames": len(shown),
        "camera": list(corr.valid.shape[::-1]),
        "same_patterns_as_slrig_gray_both": same_patterns,
        "slrig_decode_ms": round(ours * 1e3, 1),
        "opencv_decode_per_camera_ms": round(decode_per_camera * 1e3, 1),
        "opencv_get_proj_pixel_ms": round(theirs["get_proj_pixel_s"] * 1e3, 1),
        "speedup_over_decode": round(decode_per_camera / ours, 1),
        "speedup_over_get_proj_pixel": round(theirs["get_proj_pixel_s"] / ours, 1),
        "coverage_slrig": round(float(corr.valid.sum()) / pixels, 4),
        "coverage_opencv": round(float((found["u"] >= 0).sum()) / pixels, 4),
        "agreement_on_both": round(float(agree.sum()) / max(1, int(both.sum())), 5),
    }


def slrig_decode(codec: Any, frames: list[np.ndarray]) -> tuple[float, Any]:
    """Median seconds of slrig's Gray stream over the frames, and its correspondence."""
    times, corr = [], None
    for _ in range(8):
        t = time.perf_counter()
        corr = decode_streamed(codec, frames, 255)
        times.append(time.perf_counter() - t)
    return statistics.median(times[1:]), corr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite the peer table in the manual (docs/)"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="slrig-peer-") as tmp:
        work = Path(tmp)
        subprocess.run([sys.executable, "-m", "venv", str(work / "venv")], check=True, timeout=600)
        python = work / "venv" / "bin" / "python"
        subprocess.run([str(python), "-m", "pip", "install", "-q", PEER], check=True, timeout=1800)
        result = peer(python, work)
    print(json.dumps(result))
    if args.readme:
        r = result
        table = markdown_table(
            ["decoder (one 1280x1024 camera, 42 frames)", "ms", "slrig faster by", "pixels decoded"],
            [
                ["slrig Gray stream", r["slrig_decode_ms"], "", f"{r['coverage_slrig']:.1%}"],
                [
                    f"OpenCV {r['opencv_contrib']} `decode()` (per camera)",
                    r["opencv_decode_per_camera_ms"],
                    f"{r['speedup_over_decode']}x",
                    "",
                ],
                [
                    "OpenCV `getProjPixel`, every pixel",
                    r["opencv_get_proj_pixel_ms"],
                    f"{r['speedup_over_get_proj_pixel']}x",
                    f"{r['coverage_opencv']:.1%}",
                ],
            ],
        )
        replace_block(
            "peer-table",
            f"{table}\n\nOn the pixels both decode, {r['agreement_on_both']:.3%} have the same projector column "
            f"and row. Measured by `python bench/peer_opencv.py --docs` (OpenCV contrib in a throw-away venv).",
        )


if __name__ == "__main__":
    main()
