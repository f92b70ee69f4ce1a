"""Identification: a probe's descriptor against the gallery's, ranked by correlation.

Two comparisons:
- `standardised` (default): each feature less the gallery's mean and divided by its (moderated)
  spread over the gallery before the correlation, so that what every surface shares (a face is a face: the
  rings' mean excess, the nose's harmonics) does not make every pair look alike (raw correlations
  between different faces are above 0.99);
- `raw`: the published comparison, Pearson correlation of the features as they are.
A gallery of fewer than `MIN_STANDARDISED` entries has no spread to divide by; it is compared raw.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from rig.errors import RecognitionError
from rig.recognition.gallery import Entry

Comparison = Literal["standardised", "raw"]
MIN_STANDARDISED = 3
UNKNOWN = "unknown"
EMPTY_GALLERY = "the gallery is empty: add labelled scans first (slrig gallery add SCAN_DIR --label NAME)"


@dataclass(frozen=True)
class Match:
    label: str
    score: float
    entry_id: int
    scan_id: str

    def as_dict(self) -> dict[str, object]:
        return {"label": self.label, "score": round(self.score, 6), "entry_id": self.entry_id, "scan_id": self.scan_id}


@dataclass(frozen=True)
class Identification:
    label: str  # the best match's label, or UNKNOWN when its score is below the threshold
    matches: list[Match]  # best first, one per label
    threshold: float
    comparison: Comparison

    def as_dict(self) -> dict[str, object]:
        return {
            "label": self.label,
            "threshold": self.threshold,
            "comparison": self.comparison,
            "matches": [m.as_dict() for m in self.matches],
        }


def compared_as(comparison: Comparison, entries: int) -> Comparison:
    """The comparison a gallery of `entries` entries gets when `comparison` is asked for."""
    return comparison if entries >= MIN_STANDARDISED else "raw"


def standardised(features: np.ndarray, gallery: np.ndarray) -> np.ndarray:
    """`features` (..., F) less the gallery's (N, F) mean, over its moderated spread: each feature's
    spread s is taken as sqrt(s^2 + s0^2), s0 the median spread over the features (features the
    gallery holds constant: 0).

    A spread estimated from a few entries is itself uncertain, and a feature that happens to vary
    little over the gallery (a high harmonic of a smooth ring) would be multiplied up to the weight
    of the shape's own harmonics, and with it the scan noise it holds in a probe. Adding a common
    s0 to every spread, the median (the fudge factor of the SAM statistic, Tusher et al. 2001),
    weighs such features down and leaves those that vary well above the median as they were."""
    mean, spread = standard_scale(gallery)
    return (features - mean) / spread


def standard_scale(gallery: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The gallery's (N, F) mean and moderated spread per feature (see `standardised`)."""
    spread = gallery.std(axis=0)
    floor = float(np.median(spread))
    spread = np.where(spread > 1e-9 * max(float(spread.max()), 1e-300), np.hypot(spread, floor), np.inf)
    return gallery.mean(axis=0), spread


def scores(probe: np.ndarray, gallery: np.ndarray, comparison: Comparison = "standardised") -> np.ndarray:
    """(N,) the correlation of `probe` (F,) with each row of `gallery` (N, F)."""
    if compared_as(comparison, len(gallery)) == "standardised":
        gallery, probe = standardised(gallery, gallery), standardised(probe, gallery)
    rows = gallery - gallery.mean(axis=1, keepdims=True)
    centred = probe - probe.mean()
    norms = np.linalg.norm(rows, axis=1) * np.linalg.norm(centred)
    return rows @ centred / np.maximum(norms, 1e-300)


def check_probe(probe: np.ndarray, gallery: np.ndarray) -> None:
    """RecognitionError for an empty gallery (N, F) or a probe that is not F features."""
    if not len(gallery):
        raise RecognitionError(EMPTY_GALLERY)
    if probe.shape != gallery.shape[1:]:
        raise RecognitionError(f"the probe has {probe.size} features, the gallery's entries {gallery.shape[1]}")


def identify(
    probe: np.ndarray,
    entries: list[Entry],
    gallery: np.ndarray,
    top: int = 5,
    threshold: float | dict[Comparison, float] = 0.5,
    comparison: Comparison = "standardised",
) -> Identification:
    """The `top` labels best matching `probe` (each label's best entry), and the label it is
    identified as (UNKNOWN below `threshold`, or below the threshold of the comparison made when
    given one per comparison). Raises RecognitionError for an empty gallery."""
    check_probe(probe, gallery)
    comparison = compared_as(comparison, len(gallery))
    if isinstance(threshold, dict):
        threshold = threshold[comparison]
    labels = [e.label for e in entries]
    codes = np.unique(np.asarray(labels, dtype=object), return_inverse=True)[1]
    ids, scan_ids = [e.id for e in entries], [e.scan_id for e in entries]
    found = ranked(scores(probe, gallery, comparison), codes, labels, ids, scan_ids, top)
    return verdict_of(found, threshold, comparison)


def ranked(
    score: np.ndarray, codes: np.ndarray, labels: list[str], ids: list[int] | np.ndarray, scan_ids: list[str], top: int
) -> list[Match]:
    """The `top` labels by their best entry's `score`, best first (`codes`: each entry's label as
    an integer, which one sort groups)."""
    order = np.argsort(-score, kind="stable")
    _, first = np.unique(codes[order], return_index=True)  # each label's best, in order
    best = order[np.sort(first)[: max(top, 1)]]
    return [Match(labels[i], float(score[i]), int(ids[i]), scan_ids[i]) for i in best]


def verdict_of(matches: list[Match], threshold: float, comparison: Comparison) -> Identification:
    """The label identified: the best match's, or UNKNOWN below `threshold`."""
    label = matches[0].label if matches[0].score >= threshold else UNKNOWN
    return Identification(label, matches, threshold, comparison)
