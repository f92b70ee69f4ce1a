"""Real surfaces on the simulated bench: shiny, glossy and dark-and-white objects scanned with one
exposure, with auto-exposure and with HDR bracketing, beside the same shape matte. Prints one JSON
object {"scenes": {NAME: {MODE: {...}}}}: completeness (of the visible, lit surface, within 1 mm),
rms and p95 in mm, frames projected, exposures, the bench-clock capture time, and the pixels lost
to clipping (at every exposure).

    python bench/materials.py [--docs]

Modes: `single` (the camera's own exposure), `auto` (auto-exposure from a pre-capture), `hdr`
(auto-exposure, then as many exposures as the pre-capture asks for, two stops apart, merged per
pixel), `adaptive` (adaptive projection: the patterns dimmed per projector pixel where the camera
would clip, from a pre-scan, in one exposure; two passes with the masks' steps on either side of
each edge where one pass would lose many pixels beside them, as `scan.exposure.adaptive_passes:
auto` decides), `adaptive, one pass` (forced to one), and adaptive with HDR. `matte` is the same shape and exposure
with the gloss and the dark paint taken away. The codec is the config's (phase); every mode leaves
out the pixels outshone by a far brighter neighbour (scan.exposure.drop_outshone), the matte one too,
but the deblurred ones, which undo the camera's blur instead (scan.exposure.deblur_px).
Frames count the pre-scan's. With --docs it also draws docs/images/materials.png: for each scene,
which of the lit surface's pixels each of FIGURE_MODES read (grey) and missed (red).
"""

from __future__ import annotations

import platform
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.evaluate.pairs import coverage_on_bench, evaluate_on_bench, point_errors
from rig.pipeline.hdr import scan_with_exposure

IMAGE = Path(__file__).resolve().parent.parent / "docs/images/materials.png"
FIGURE_MODES = ("matte", "single", "hdr", "adaptive")
_COVERAGE: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}  # (scene, mode): lit surface, read (H, W)

DARK_AND_WHITE = {"kind": "checker", "size_mm": 25.0, "colours": [[0.02] * 3, [1.0] * 3]}
# name: (scene, material, texture)
SCENES: dict[str, tuple[dict[str, Any], dict[str, Any], dict[str, Any] | None]] = {
    "machined steps": ({"kind": "steps"}, {"specular": 0.8, "roughness": 0.08}, None),
    "glossy sphere": ({"kind": "sphere_on_plane"}, {"specular": 0.5, "roughness": 0.15}, None),
    "dark and white box": ({"kind": "box"}, {"specular": 0.0}, DARK_AND_WHITE),
}
MODES: dict[str, dict[str, Any]] = {
    "matte": {"exposure": "camera", "hdr": None},
    "single": {"exposure": "camera", "hdr": None},
    "auto": {"exposure": "auto", "hdr": None},
    "hdr": {"exposure": "auto", "hdr": "auto"},
    "adaptive": {"exposure": "auto", "hdr": None, "adaptive_projection": True},
    "adaptive, one pass": {"exposure": "auto", "hdr": None, "adaptive_projection": True, "adaptive_passes": 1},
    "adaptive + hdr": {"exposure": "auto", "hdr": "auto", "adaptive_projection": True},
    # the camera's blur (0.6 px on this bench) undone instead of the outshone pixels left out
    "auto, deblurred": {"exposure": "auto", "hdr": None, "deblur_px": 0.6, "drop_outshone": False},
    "hdr, deblurred": {"exposure": "auto", "hdr": "auto", "deblur_px": 0.6, "drop_outshone": False},
}


def measure_scene(
    scene: dict[str, Any], material: dict[str, Any], texture: dict[str, Any] | None, mode: str, name: str = ""
) -> dict:
    data = load_config().model_dump(mode="json")
    data["simulation"]["scene"] = scene
    if mode != "matte":
        data["simulation"]["material"] = material
        data["simulation"]["texture"] = texture
    data["scan"]["exposure"] = {"drop_outshone": True, **MODES[mode]}
    with open_rig(config_from_dict(data, f"materials {mode}")) as rig:
        assert rig.truth is not None
        start = rig.truth.clock_s
        result = scan_with_exposure(rig)
        capture_s = rig.truth.clock_s - start
        errors = point_errors(rig, result.pairs[0])
        metrics = evaluate_on_bench(rig, result.pairs[0], errors)
        if mode in FIGURE_MODES:
            _COVERAGE[(name, mode)] = coverage_on_bench(rig, result.pairs[0], errors)
    counts = result.pairs[0].counts
    exposure = result.exposure or {}
    return {
        "completeness": round(float(metrics["completeness"]), 4),
        "rms_mm": None if metrics["rms_mm"] is None else round(float(metrics["rms_mm"]), 4),
        "p95_mm": None if metrics["p95_mm"] is None else round(float(metrics["p95_mm"]), 4),
        "frames": result.frames_projected,
        "exposures_us": exposure.get("exposures_us"),
        "capture_s": round(capture_s, 3),
        "rejected_saturated": counts.get("rejected_saturated", 0),
    }


def measure_all() -> dict[str, Any]:
    return {
        "benchmark": "materials",
        "python": platform.python_version(),
        "scenes": {
            name: {mode: measure_scene(scene, material, texture, mode, name) for mode in MODES}
            for name, (scene, material, texture) in SCENES.items()
        },
    }


def table(measured: dict[str, Any]) -> str:
    rows = []
    for name, modes in measured["scenes"].items():
        for mode, m in modes.items():
            exposures = next(iter((m["exposures_us"] or {}).values()), None)
            shown = ", ".join(f"{e / 1000:.3g}" for e in exposures) if exposures else "camera's"
            cells = [name, mode, f"{100 * m['completeness']:.1f} %", m["rms_mm"], m["p95_mm"], m["frames"], shown]
            rows.append([*cells, m["capture_s"], m["rejected_saturated"]])
    header = ["scene", "mode", "completeness", "rms mm", "p95 mm", "frames", "exposures ms", "capture s"]
    header.append("clipped px lost")
    if _COVERAGE:
        figure(measured, IMAGE)
    return markdown_table(header, rows) + "\n\nProduced by `python bench/materials.py --docs`."


def figure(measured: dict[str, Any], path: Path, scale: int = 4) -> None:
    """A row per scene, a column per FIGURE_MODES: the camera's view, each lit surface pixel grey
    where the mode read it within 1 mm, red where it did not; its completeness in the corner."""
    rows = []
    for name in measured["scenes"]:
        panels = []
        for mode in FIGURE_MODES:
            target, covered = _COVERAGE[(name, mode)]
            image = np.full((*target.shape, 3), 40, np.uint8)
            image[target] = (40, 40, 220)
            image[covered] = (205, 205, 205)
            size = (target.shape[1] // scale, target.shape[0] // scale)
            small = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
            text = f"{mode}: {100 * measured['scenes'][name][mode]['completeness']:.1f} %"
            (width, height), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 1)
            cv2.rectangle(small, (0, 0), (width + 14, height + 14), (30, 30, 30), -1)  # legible over any panel
            cv2.putText(small, text, (7, height + 7), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
            panels.append(cv2.copyMakeBorder(small, 3, 3, 3, 3, cv2.BORDER_CONSTANT, value=(255, 255, 255)))
        row = np.hstack(panels)
        label = np.full((30, row.shape[1], 3), 255, np.uint8)
        cv2.putText(label, name, (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.65, (0, 0, 0), 1, cv2.LINE_AA)
        rows.append(np.vstack([label, row]))
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.vstack(rows))


def main() -> None:
    run(__doc__ or "", "materials-table", measure_all, table)


if __name__ == "__main__":
    main()
