"""Make the README's pictures from a scan of the default simulated bench.

python docs/make_images.py
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import cv2
import numpy as np

from rig.assembly import open_rig
from rig.config import REPO_CONFIG_DIR, config_from_dict, load_config
from rig.geometry import CameraModel, look_at_rotation
from rig.pipeline.capture import CUE
from rig.pipeline.colour import interpolate_colour, sample_colours
from rig.pipeline.dense import texture_rgb
from rig.pipeline.results import PairResult
from rig.pipeline.scan import make_codec, run_scan
from rig.service.adaptive import adaptive_scan
from rig.store.images import preview_png

OUT = Path(__file__).resolve().parent / "images"
CHART = Path(__file__).resolve().parent.parent / "config/textures/chart.png"


def _save(name: str, image: np.ndarray, width: int = 640) -> None:
    scale = width / image.shape[1]
    small = cv2.resize(image, (width, round(image.shape[0] * scale)), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(OUT / name), small)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    if "--colour" in sys.argv:  # only the colour pictures
        _colour()
        return
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
    _surface()
    _colour()


def _surface() -> None:
    """An adaptive ring scan (planned for 0.05 mm): its ring points, and the surface interpolated
    between them, shaded by its normals (light from the camera's upper left), as the camera sees
    them; and the same for 16 evenly spaced rings, which leave the sphere's limb unknown."""
    with open_rig(load_config()) as rig:
        result = adaptive_scan(rig, 0.05)[0]
        _surface_pair("planned", rig.camera_models[0], result.pairs[0])
        data = load_config().with_codec("rings").model_dump(mode="json")
        data["scan"]["rings"]["rings"] = 16
        uniform = dataclasses.replace(rig, config=config_from_dict(data, "16 rings"))
        _surface_pair("uniform16", rig.camera_models[0], run_scan(uniform).pairs[0])


def _colour() -> None:
    """The chart texture on the default bench, seen by a colour camera: its true colour, the white
    frame, and the colour interpolated from 32 rings' samples alone (L-NN and density-compensated),
    cropped to the sphere and the chart around it."""
    data = load_config().with_codec("rings").model_dump(mode="json")
    data["simulation"]["texture"] = {"kind": "image", "path": str(CHART), "size_mm": 240.0}
    data["cameras"][0]["color"] = True
    data["scan"]["surface"]["mesh_stride_px"] = 1
    with open_rig(config_from_dict(data, "chart")) as rig:
        pair = run_scan(rig).pairs[0]
        assert pair.surface is not None and pair.rings is not None and rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
    crop = (slice(212, 812), slice(340, 1090))
    white = cv2.cvtColor(texture_rgb(pair.correspondence), cv2.COLOR_RGB2BGR)
    shading = np.clip(truth.white_irradiance, 0, None)[..., None] * float(np.median(white[truth.hit] / 255.0))
    true = np.clip(truth.albedo[..., ::-1] * shading * 255 / np.median(shading[truth.hit]), 0, 255)
    _save("colour_truth.png", true.astype(np.uint8)[crop], 360)
    _save("colour_white.png", white[crop], 360)
    corr = pair.correspondence
    samples = sample_colours(corr.texture, pair.rings.camera_xy[pair.rings.kept], corr.full_scale)
    for method in ("nearest", "area"):
        colour = interpolate_colour(pair.surface, samples, method)  # type: ignore[arg-type]
        image = np.full(colour.shape, 255, np.uint8)
        ok = np.isfinite(colour).all(axis=2)
        image[ok] = np.clip(colour[ok][:, ::-1] * 255, 0, 255).astype(np.uint8)
        _save(f"colour_{method}.png", image[crop], 360)


def _surface_pair(name: str, camera: CameraModel, pair: PairResult) -> None:
    assert pair.surface is not None and pair.rings is not None
    dots = np.full((*pair.surface.valid.shape, 3), 255, np.uint8)
    xy = np.rint(pair.rings.camera_xy[pair.rings.kept]).astype(int)
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        rows, cols = np.clip(xy[:, 1] + dy, 0, dots.shape[0] - 1), np.clip(xy[:, 0] + dx, 0, dots.shape[1] - 1)
        dots[rows, cols] = (90, 40, 0)
    _save(f"surface_{name}_rings.png", dots)
    _save(f"surface_{name}_mesh.png", _shaded(pair.surface.grid, camera))


def _shaded(grid: np.ndarray, camera: CameraModel) -> np.ndarray:
    """Lambert shading of an organised surface from its pixel neighbours' normals; holes white."""
    du = np.roll(grid, -1, axis=1) - np.roll(grid, 1, axis=1)
    dv = np.roll(grid, -1, axis=0) - np.roll(grid, 1, axis=0)
    normal = np.cross(du, dv)
    normal /= np.linalg.norm(normal, axis=2, keepdims=True) + 1e-12
    toward = camera.center - grid
    normal *= np.sign(np.einsum("ijk,ijk->ij", normal, toward))[..., None]
    light = camera.R.T @ np.array([-0.4, -0.5, -0.77])  # camera frame: x right, y down, z forward
    light /= np.linalg.norm(light)
    value = np.clip(np.einsum("ijk,k->ij", normal, light), 0.0, 1.0)
    image = np.full((*grid.shape[:2], 3), 255, np.uint8)
    ok = np.isfinite(value)
    shade = (40 + 200 * value[ok]).astype(np.uint8)
    image[ok] = np.column_stack([shade, (0.95 * shade).astype(np.uint8), (0.85 * shade).astype(np.uint8)])
    return image


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
