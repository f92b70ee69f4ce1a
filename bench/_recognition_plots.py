"""The pictures of bench/recognition.py: rank-1 against the ring count, and the correlation matrix
of the face scans' default descriptors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
from _face_scans import Case

from rig.recognition.descriptor import correlation
from rig.recognition.identify import standardised

COLOURS = {  # BGR
    "geodesic": (180, 80, 0),
    "geodesic, published": (200, 170, 90),
    "euclidean": (40, 150, 40),
    "eigen-depth": (0, 0, 200),
}
FONT = cv2.FONT_HERSHEY_SIMPLEX


def rank_one_plot(report: dict[str, Any], path: Path) -> None:
    """Rank-1 (all probes) against the ring count, one line per descriptor, the planner's count marked."""
    width, height, margin = 640, 360, 56
    canvas = np.full((height, width, 3), 255, np.uint8)
    counts = [r["rings"] for r in report["counts"]]
    low, high = min([*counts, report["planned"]["rings"]]) - 2, max(counts) + 4

    def to_px(n: float, rate: float) -> tuple[int, int]:
        x = margin + (n - low) / (high - low) * (width - 1.6 * margin)
        return int(x), int(height - margin - rate * (height - 1.7 * margin))

    for rate in (0.0, 0.25, 0.5, 0.75, 0.95, 1.0):
        y = to_px(low, rate)[1]
        cv2.line(canvas, (margin, y), (width - margin // 2, y), (225, 225, 225), 1)
        cv2.putText(canvas, f"{100 * rate:.0f}%", (6, y + 4), FONT, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for n in counts:
        x, y = to_px(n, 0.0)
        cv2.putText(canvas, str(n), (x - 8, y + 18), FONT, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    planned = report["planned"]["rings"]
    x, _ = to_px(planned, 0.0)
    cv2.line(canvas, (x, to_px(planned, 1.0)[1]), (x, to_px(planned, 0.0)[1]), (0, 140, 255), 1, cv2.LINE_AA)
    cv2.putText(canvas, f"plan: {planned}", (x + 4, margin - 8), FONT, 0.45, (0, 140, 255), 1, cv2.LINE_AA)
    for row, (name, colour) in enumerate(COLOURS.items()):
        line = [to_px(r["rings"], r["methods"][name]["rank1"]) for r in report["counts"]]
        cv2.polylines(canvas, [np.array(line, np.int32)], False, colour, 2, cv2.LINE_AA)
        for p in line:
            cv2.circle(canvas, p, 3, colour, -1, cv2.LINE_AA)
        cv2.putText(canvas, name, (margin + 10, height - margin - 60 - 16 * row), FONT, 0.45, colour, 1, cv2.LINE_AA)
    cv2.putText(canvas, "rank-1 against rings", (margin, 22), FONT, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(canvas, "rings", (width // 2, height - 12), FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), canvas)


def correlation_image(cases: list[Case], features: list[np.ndarray | None], path: Path, cell: int = 8) -> None:
    """Every scan against every scan: the correlation of their default descriptors, standardised
    by the gallery's spread as identification compares them; scans grouped by identity."""
    gallery = np.array([f for c, f in zip(cases, features, strict=True) if c.group == "gallery" and f is not None])
    n = len(cases)
    matrix = np.full((n, n), np.nan)
    for i, a in enumerate(features):
        for j, b in enumerate(features):
            if a is not None and b is not None:
                matrix[i, j] = correlation(standardised(a, gallery), standardised(b, gallery))
    scaled = np.clip((np.nan_to_num(matrix, nan=-1.0) + 1.0) / 2.0 * 255.0, 0, 255).astype(np.uint8)
    image = cv2.applyColorMap(np.kron(scaled, np.ones((cell, cell), np.uint8)), cv2.COLORMAP_VIRIDIS)
    label = 70
    canvas = np.full((n * cell + label, n * cell + label, 3), 255, np.uint8)
    canvas[label:, label:] = image
    per_identity = sum(c.identity == cases[0].identity for c in cases)
    for start in range(0, n, per_identity):
        at = label + start * cell
        cv2.line(canvas, (at, label), (at, label + n * cell), (255, 255, 255), 1)
        cv2.line(canvas, (label, at), (label + n * cell, at), (255, 255, 255), 1)
        cv2.putText(canvas, f"{cases[start].identity}", (at + 4, label - 6), FONT, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(canvas, f"{cases[start].identity}", (label - 22, at + 14), FONT, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(canvas, "identity", (label, 20), FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(canvas, "-1 .. 1", (4, 20), FONT, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), canvas)
