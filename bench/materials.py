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
Frames count the pre-scan's.
"""

from __future__ import annotations

import platform
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.evaluate.pairs import evaluate_on_bench
from rig.pipeline.hdr import scan_with_exposure

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


def measure_scene(scene: dict[str, Any], material: dict[str, Any], texture: dict[str, Any] | None, mode: str) -> dict:
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
        metrics = evaluate_on_bench(rig, result.pairs[0])
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
            name: {mode: measure_scene(scene, material, texture, mode) for mode in MODES}
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
    return markdown_table(header, rows) + "\n\nProduced by `python bench/materials.py --docs`."


def main() -> None:
    run(__doc__ or "", "materials-table", measure_all, table)


if __name__ == "__main__":
    main()
