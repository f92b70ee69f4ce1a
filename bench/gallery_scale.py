"""Identification at archive scale: a gallery of 100,000 entries (10,000 labels of 10, descriptors
of the default settings' 264 features), and a probe identified against it as `slrig identify` and
the daemon do (rig.recognition.matrix). Prints one JSON object: the time to add the entries in one
transaction, to read and prepare the matrix the first time, and per probe after that (p50 and p95
over 50 probes), and the matrix's memory.

    python bench/gallery_scale.py [--docs]

The descriptors are random (the time does not depend on their values); describing the probe's scan
is not included (it is the same whatever the gallery's size).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.recognition.descriptor import Descriptor, DescriptorSettings
from rig.recognition.gallery import Gallery
from rig.recognition.matrix import read_matrix

ENTRIES, PER_LABEL, PROBES = 100_000, 10, 50


def measure() -> dict[str, Any]:
    settings = DescriptorSettings()
    features = settings.rings * (settings.samples // 2 + 1)
    rng = np.random.default_rng(1)
    shapes = rng.normal(size=(ENTRIES // PER_LABEL, features))
    distances, reference, axis = np.zeros((settings.rings, settings.samples)), np.zeros(3), np.array([0.0, 0.0, 1.0])
    items = [
        (f"label-{n // PER_LABEL}", f"scan-{n}", Descriptor(shapes[n // PER_LABEL] + 0.1 * rng.normal(size=features),
                                                           distances, reference, axis, settings))
        for n in range(ENTRIES)
    ]  # fmt: skip
    with tempfile.TemporaryDirectory() as folder, Gallery(Path(folder) / "gallery.db") as gallery:
        start = time.perf_counter()
        gallery.add_many(items)
        added_s = time.perf_counter() - start
        start = time.perf_counter()
        matrix = read_matrix(gallery)
        matrix.identify(items[0][2].features)  # the first probe prepares the comparison's rows
        first_s = time.perf_counter() - start
        times, right = [], 0
        for _ in range(PROBES):
            label = int(rng.integers(len(shapes)))
            probe = shapes[label] + 0.1 * rng.normal(size=features)
            tick = time.perf_counter()
            found = matrix.identify(probe)
            times.append(time.perf_counter() - tick)
            right += found.label == f"label-{label}"
    prepared = sum(rows.nbytes for rows in matrix._prepared.values()) + matrix.features.nbytes
    return {
        "benchmark": "gallery_scale",
        "entries": ENTRIES,
        "features": features,
        "add_s": round(added_s, 2),
        "first_identify_s": round(first_s, 2),
        "identify_ms_p50": round(1000 * float(np.median(times)), 1),
        "identify_ms_p95": round(1000 * float(np.percentile(times, 95)), 1),
        "identified_right": right / PROBES,
        "matrix_mb": round(prepared / 1e6),
    }


def table(m: dict[str, Any]) -> str:
    rows = [[m["entries"], m["features"], m["add_s"], m["first_identify_s"], m["identify_ms_p50"], m["identify_ms_p95"],
             m["matrix_mb"]]]  # fmt: skip
    header = ["entries", "features", "add s (one transaction)", "first identify s", "identify ms p50", "p95",
              "matrix MB"]  # fmt: skip
    return markdown_table(header, rows) + "\n\nProduced by `python bench/gallery_scale.py --docs`."


def main() -> None:
    run(__doc__ or "", "gallery-scale-table", measure, table)


if __name__ == "__main__":
    main()
