"""Recognition of scanned faces (dissertation ch.8): rank-1 identification and equal error rate of
the geodesic ring descriptor, the published variant, the Euclidean one and an eigen-depth (PCA)
baseline, on the synthetic face set scanned with rings on the simulated bench, for several ring
counts. Prints one JSON object; with --docs also rewrites the recognition tables in the manual (docs/)
and draws docs/images/recognition_rank1.png and docs/images/recognition_correlation.png.

    python bench/recognition.py [--docs] [--identities 10] [--counts 12,16,24,32,48,64] [--cache DIR]

Faces: drivers/sim/faces.py (the MeshMonk template, `pip install --no-deps autofacemonker==0.2.0`);
per identity five expressions (neutral, smile, surprise, frown, puff) and the neutral face in two
poses (POSES in bench/_face_scans.py). The gallery holds each identity's neutral scan; every other
scan is a probe. Scans are cached in --cache (default: a temporary directory) as .npz files.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _face_scans
import _recognition_plots
from _readme import markdown_table, replace_block

from rig.errors import RecognitionError
from rig.progress import ProgressTracker, StageLines, TerminalBar
from rig.recognition.descriptor import Descriptor, DescriptorSettings, describe
from rig.recognition.eigendepth import EigenDepth, depth_map
from rig.recognition.evaluation import equal_error_rate, genuine_and_impostor, rank_one
from rig.recognition.identify import Comparison, scores

ROOT = Path(__file__).resolve().parent.parent
COUNTS = [12, 16, 24, 32, 48, 64]
MAIN_COUNT = 32  # the bench's default ring count: the manual's main table


@dataclass(frozen=True)
class Method:
    settings: DescriptorSettings | None  # None: eigen-depth
    comparison: Comparison
    about: str


METHODS = {
    "geodesic": Method(DescriptorSettings(), "standardised", "slrig's default: per-ring spectra, balanced frame"),
    "geodesic, published": Method(
        DescriptorSettings(spectrum="concatenated", frame="viewer"), "raw", "the dissertation's: one spectrum, raw"
    ),
    "euclidean": Method(DescriptorSettings(distance="euclidean"), "standardised", "the default with 3D distances"),
    "eigen-depth": Method(None, "raw", "PCA of depth maps in the default's frame, Mahalanobis cosine"),
}


def describe_all(
    scans: list[_face_scans.FaceScan], settings: DescriptorSettings
) -> tuple[list[Descriptor | None], float]:
    """Each scan's descriptor (None where it cannot be described) and the median seconds per scan."""
    found: list[Descriptor | None] = []
    seconds = []
    for s in scans:
        t0 = time.perf_counter()
        try:
            found.append(describe(s.points, s.toward_viewer, settings))
        except RecognitionError:
            found.append(None)
        seconds.append(time.perf_counter() - t0)
    return found, float(np.median(seconds))


def score_matrix(
    features: list[np.ndarray | None], gallery: list[int], probes: list[int], comparison: Comparison
) -> np.ndarray:
    """(P, G) scores; -1 (the lowest correlation) for a scan that could not be described."""
    size = next(len(f) for f in features if f is not None)
    matrix = np.array([f if f is not None else np.full(size, np.nan) for f in features])
    known = [g for g in gallery if np.isfinite(matrix[g]).all()]
    result = np.full((len(probes), len(gallery)), -1.0)
    columns = [gallery.index(g) for g in known]
    for row, p in enumerate(probes):
        if np.isfinite(matrix[p]).all() and known:
            result[row, columns] = scores(matrix[p], matrix[known], comparison)
    return result


def eigen_depth_scores(
    scans: list[_face_scans.FaceScan], frames: list[Descriptor | None], gallery: list[int], probes: list[int]
) -> np.ndarray:
    """Eigen-depth similarities, the depth maps taken about each scan's default descriptor frame."""
    radius = DescriptorSettings().outer_mm
    maps: list[np.ndarray | None] = []
    for s, frame in zip(scans, frames, strict=True):
        try:
            maps.append(None if frame is None else depth_map(s.points, frame.reference, frame.axis, radius))
        except RecognitionError:
            maps.append(None)
    known = [g for g in gallery if maps[g] is not None]
    model = EigenDepth.fit(np.array([maps[g] for g in known]))
    result = np.full((len(probes), len(gallery)), -1.0)
    columns = [gallery.index(g) for g in known]
    rows = [r for r, p in enumerate(probes) if maps[p] is not None]
    if rows:
        probe_maps = np.array([maps[probes[r]] for r in rows])
        result[np.ix_(rows, columns)] = model.similarity(probe_maps, np.array([maps[g] for g in known]))
    return result


def evaluate(score: np.ndarray, cases: list[_face_scans.Case], gallery: list[int], probes: list[int]) -> dict[str, Any]:
    probe_labels = [str(cases[p].identity) for p in probes]
    gallery_labels = [str(cases[g].identity) for g in gallery]
    hit = rank_one(score, probe_labels, gallery_labels)
    groups = np.array([cases[p].group for p in probes])
    verification = equal_error_rate(*genuine_and_impostor(score, probe_labels, gallery_labels))
    return {
        "rank1": round(float(hit.mean()), 4),
        "rank1_expressions": round(float(hit[groups == "expression"].mean()), 4),
        "rank1_poses": round(float(hit[groups == "pose"].mean()), 4),
        "missed": [cases[p].name for p, h in zip(probes, hit, strict=True) if not h],
        "eer": round(verification.equal_error_rate, 4),
        "eer_threshold": round(verification.threshold, 4),
    }


def measure_count(
    cases: list[_face_scans.Case],
    rings: int,
    cache: Path,
    bench: Path | None = None,
    scanned: Callable[[str], None] = lambda name: None,
) -> dict[str, Any]:
    t0 = time.perf_counter()
    scans = []
    for case in cases:
        scans.append(_face_scans.scan(case, rings, cache, bench))
        scanned(case.name)
    scan_s = time.perf_counter() - t0
    gallery = [i for i, c in enumerate(cases) if c.group == "gallery"]
    probes = [i for i, c in enumerate(cases) if c.group != "gallery"]
    results: dict[str, Any] = {}
    frames: list[Descriptor | None] = []
    default_features: list[np.ndarray | None] = []
    for name, method in METHODS.items():
        if method.settings is None:
            score = eigen_depth_scores(scans, frames, gallery, probes)
            seconds = None
        else:
            descriptors, seconds = describe_all(scans, method.settings)
            if name == "geodesic":
                frames = descriptors
                default_features = [None if d is None else d.features for d in descriptors]
            features = [None if d is None else d.features for d in descriptors]
            score = score_matrix(features, gallery, probes, method.comparison)
        results[name] = {**evaluate(score, cases, gallery, probes), "describe_s": seconds}
    return {
        "rings": rings,
        "points_median": int(np.median([len(s.points) for s in scans])),
        "scan_s_median": round(float(np.median([s.seconds for s in scans])), 2),
        "scan_wall_s": round(scan_s, 1),
        "methods": results,
        "_features": default_features,
    }


def readme_tables(report: dict[str, Any]) -> str:
    main = next(r for r in report["counts"] if r["rings"] == report["main_count"])
    header = ["descriptor", "rank-1 all", "rank-1 expressions", "rank-1 poses", "EER", "EER threshold", "what it is"]
    rows = [
        [
            name,
            *(f"{100 * m[k]:.1f} %" for k in ("rank1", "rank1_expressions", "rank1_poses", "eer")),
            f"{m['eer_threshold']:.4f}",
            METHODS[name].about,
        ]
        for name, m in main["methods"].items()
    ]
    by_count = ["descriptor", *(str(r["rings"]) for r in report["counts"])]
    count_rows = [[name, *(_all_and_poses(r["methods"][name]) for r in report["counts"])] for name in METHODS]
    return (
        f"{report['main_count']} rings, {report['identities']} identities, {report['probes']} probes:\n\n"
        + markdown_table(header, rows)
        + "\n\nRank-1 (%) over all probes (and over the posed ones) against the ring count "
        + "(the planner's count for the first "
        + f"identity's neutral face: {report['planned']['rings']} rings at {report['planned']['tolerance_mm']} mm):\n\n"
        + markdown_table(by_count, count_rows)
    )


def _all_and_poses(found: dict[str, Any]) -> str:
    return f"{100 * found['rank1']:.1f} ({100 * found['rank1_poses']:.0f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite README.md's tables and the plots"
    )
    parser.add_argument("--identities", type=int, default=10)
    parser.add_argument("--counts", default=",".join(str(c) for c in COUNTS), help="comma-separated ring counts")
    parser.add_argument("--cache", type=Path, help="keep the face scans here (default: a temporary directory)")
    parser.add_argument("--bench", type=Path, help="the rig config to set the faces on (default: the default bench)")
    args = parser.parse_args()
    counts = sorted({int(c) for c in args.counts.split(",") if c})
    main_count = MAIN_COUNT if MAIN_COUNT in counts else counts[-1]
    cases = _face_scans.cases(args.identities)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        cache = args.cache or Path(scratch)
        planned = _face_scans.planned_rings(cases[0])
        tracker = ProgressTracker(TerminalBar() if sys.stderr.isatty() else StageLines())  # on stderr: stdout is JSON
        measured = []
        for k, n in enumerate(counts):
            done = iter(range(1, len(cases) + 1))

            def scanned(name: str, k: int = k, n: int = n, done: Iterator[int] = done) -> None:
                tracker.report(f"{n} rings", (k + next(done) / len(cases)) / len(counts), name)

            measured.append(measure_count(cases, n, cache, args.bench, scanned))
    features = next(m.pop("_features") for m in measured if m["rings"] == main_count)
    for m in measured:
        m.pop("_features", None)
    report = {
        "benchmark": "recognition",
        "python": platform.python_version(),
        "identities": args.identities,
        "probes": sum(c.group != "gallery" for c in cases),
        "main_count": main_count,
        "planned": planned,
        "counts": measured,
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    print(json.dumps(report))
    if args.readme:
        replace_block("recognition", readme_tables(report))
        _recognition_plots.rank_one_plot(report, ROOT / "docs/images/recognition_rank1.png")
        _recognition_plots.correlation_image(cases, features, ROOT / "docs/images/recognition_correlation.png")


if __name__ == "__main__":
    main()
