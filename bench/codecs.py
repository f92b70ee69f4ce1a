"""The four codecs on the default scene, side by side: pattern economy and accuracy, as the
dissertation compares codecs by data size. Prints one JSON object.

    python bench/codecs.py            # JSON
    python bench/codecs.py --docs   # also rewrite the codec table in the manual (docs/)
"""

from __future__ import annotations

import platform
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import ACCURACY_HEADER, accuracy_cells, markdown_table, run
from speed import reconstruction

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.evaluate.pairs import evaluate_pair
from rig.pipeline.scan import run_scan

# (label, codec, parameters over the default config's)
CODECS: list[tuple[str, str, dict[str, Any]]] = [
    ("gray", "gray", {}),
    ("phase", "phase", {}),
    ("rings", "rings", {}),
    ("rings, radius only", "rings", {"tangential_period_px": None}),
    ("radial", "radial", {}),
]


def measure(label: str, codec: str, params: dict[str, Any]) -> dict[str, object]:
    data = load_config().with_codec(codec).model_dump(mode="json")
    data["scan"][codec] = {**(data["scan"].get(codec) or {}), **params}
    config = config_from_dict(data, label)
    with open_rig(config) as rig:
        result = run_scan(rig)
        pair = result.pairs[0]
        assert rig.truth is not None
        metrics = evaluate_pair(pair, rig.truth.ground_truth(0, 0), rig.truth)
    timing = reconstruction(codec, config=config)
    return {
        "codec": label,
        "frames": result.frames_projected,
        "mb_captured": round(result.bytes_captured / 1e6, 1),
        **{k: (round(v, 6) if isinstance(v, float) else v) for k, v in metrics.items()},
        "decode_triangulate_ms": timing["decode_triangulate_ms"],
        "counts": pair.counts,
    }


def measure_all() -> dict[str, object]:
    return {
        "benchmark": "codecs",
        "scene": "sphere_on_plane (config/sim.yaml)",
        "python": platform.python_version(),
        "results": [measure(*variant) for variant in CODECS],
    }


def table(measured: dict[str, Any]) -> str:
    rows = [[*accuracy_cells(r, 3), r["decode_triangulate_ms"]] for r in measured["results"]]
    header = [*ACCURACY_HEADER, "decode+triangulate ms"]
    return markdown_table(header, rows) + "\n\nProduced by `python bench/codecs.py --docs`."


def main() -> None:
    run(__doc__ or "", "codec-table", measure_all, table)


if __name__ == "__main__":
    main()
