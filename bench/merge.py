"""Several pairs merged: config/sim-multi.yaml (two heads around a box), each pair and the merged
cloud measured on the same visible surface, the intensity cue's overlap against the truth, and
the time merging takes. Prints one JSON object.

    python bench/merge.py            # JSON
    python bench/merge.py --docs   # also rewrite the merge table in the manual (docs/)
"""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.assembly import open_rig
from rig.config import REPO_CONFIG_DIR, load_config
from rig.evaluate.merged import evaluate_merge
from rig.pipeline.scan import run_scan


def measure() -> dict[str, object]:
    with open_rig(load_config(REPO_CONFIG_DIR / "sim-multi.yaml")) as rig:
        start = time.perf_counter()
        result = run_scan(rig)
        seconds = time.perf_counter() - start
        report = evaluate_merge(rig, result)
    assert result.merge is not None
    return {
        "config": "config/sim-multi.yaml",
        "scan_s": round(seconds, 2),
        "merge_ms": round(result.timings_ms.get("merge_ms", 0.0), 1),
        "merge": {k: v for k, v in result.merge.items() if k != "alignment"},
        **report,
        "machine": f"{platform.machine()}, {platform.python_version()}",
    }


def table(measured: dict[str, object]) -> str:
    rows = [
        [name, p["points"], p["rms_mm"], p["p95_mm"], f"{p['completeness']:.1%}"]
        for name, p in measured["pairs"].items()  # type: ignore[attr-defined]
    ]
    m = measured["merged"]
    rows.append(["**merged**", m["points"], m["rms_mm"], m["p95_mm"], f"{m['completeness']:.1%}"])  # type: ignore[index]
    cue = measured["overlap_cue"]
    cue_text = "; ".join(f"{c}: precision {s['precision']:.3f}, recall {s['recall']:.3f}" for c, s in cue.items())  # type: ignore[attr-defined]
    merge = measured["merge"]
    return (
        markdown_table(["pair (projector/camera)", "points", "rms mm", "p95 mm", "completeness"], rows)
        + f"\n\nMerging removed {merge['removed_fraction']:.1%} of {merge['points_in']} points "  # type: ignore[index]
        f"({merge['redundant_removed']} redundant, {merge['thinned_removed']} by thinning at "  # type: ignore[index]
        f"{merge['voxel_mm']} mm) in {measured['merge_ms']} ms; merged points closer than half the sampling "  # type: ignore[index]
        f"distance to another pair's: {m['cross_pair_within_half_sampling']:.2%}. "  # type: ignore[index]
        f"Overlap by the intensity cue, against the truth of which projectors light each pixel: {cue_text}. "
        f"Measured by `python bench/merge.py --docs` ({measured['machine']})."
    )


def main() -> None:
    run(__doc__ or "", "merge-table", measure, table)


if __name__ == "__main__":
    main()
