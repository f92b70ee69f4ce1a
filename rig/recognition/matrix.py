"""A gallery as one matrix, ready for identification at archive scale (100,000 entries and more).

`rig.recognition.identify.scores` standardises the whole gallery for every probe: at 100,000
entries of 264 features that is several passes over 211 MB. Here each comparison's rows are
prepared once (standardised, centred and scaled to unit length: what the correlation divides by),
so a probe costs one matrix-vector product, and the best match per label comes from one sort.
The scores are those of `scores` (the same correlation, in the same float64). A matrix is kept per
gallery file while the gallery is unchanged (`matrix_of`), so the daemon reads a gallery once.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rig.recognition.gallery import Gallery
from rig.recognition.identify import (
    Comparison,
    Identification,
    check_probe,
    compared_as,
    ranked,
    standard_scale,
    verdict_of,
)


def _unit_rows(rows: np.ndarray) -> np.ndarray:
    """Each row less its mean, over its length (a row of zeros stays zero), in place."""
    rows -= rows.mean(axis=1, keepdims=True)
    rows /= np.maximum(np.linalg.norm(rows, axis=1, keepdims=True), 1e-300)
    return rows


@dataclass
class GalleryMatrix:
    """Entries (ids, labels, scan ids) and their features, one row each; the prepared rows of each
    comparison are made on first use."""

    ids: np.ndarray  # (N,) int64
    labels: list[str]
    scan_ids: list[str]
    features: np.ndarray  # (N, F) float64
    signature: tuple[object, ...] = ()
    _label_codes: np.ndarray = field(init=False, repr=False)
    _prepared: dict[str, np.ndarray] = field(default_factory=dict, init=False, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, init=False, repr=False)
    _scale: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False)  # standardising's mean and spread

    def __post_init__(self) -> None:
        _, self._label_codes = np.unique(np.asarray(self.labels, dtype=object), return_inverse=True)

    def __len__(self) -> int:
        return len(self.ids)

    def _rows(self, comparison: Comparison) -> np.ndarray:
        with self._lock:
            if comparison not in self._prepared:
                rows = self.features
                if comparison == "standardised":
                    self._scale = standard_scale(self.features)
                    rows = (rows - self._scale[0]) / self._scale[1]
                self._prepared[comparison] = _unit_rows(np.array(rows, dtype=np.float64))
            return self._prepared[comparison]

    def scores(self, probe: np.ndarray, comparison: Comparison = "standardised") -> np.ndarray:
        """(N,) the correlation of `probe` (F,) with each entry (rig.recognition.identify.scores)."""
        comparison = compared_as(comparison, len(self))
        rows = self._rows(comparison)
        centred = (probe - self._scale[0]) / self._scale[1] if comparison == "standardised" else probe
        return rows @ _unit_rows(np.array(centred, dtype=np.float64)[None, :])[0]

    def identify(
        self,
        probe: np.ndarray,
        top: int = 5,
        threshold: float | dict[Comparison, float] = 0.5,
        comparison: Comparison = "standardised",
    ) -> Identification:
        """As rig.recognition.identify.identify, on the prepared rows."""
        check_probe(probe, self.features)
        comparison = compared_as(comparison, len(self))
        limit = threshold[comparison] if isinstance(threshold, dict) else threshold
        found = ranked(self.scores(probe, comparison), self._label_codes, self.labels, self.ids, self.scan_ids, top)
        return verdict_of(found, limit, comparison)


def read_matrix(gallery: Gallery) -> GalleryMatrix:
    """The gallery's entries as a GalleryMatrix (an empty gallery: no rows)."""
    ids, labels, scan_ids, features = gallery.columns()
    return GalleryMatrix(ids, labels, scan_ids, features, gallery.signature())


_cache: dict[Path, GalleryMatrix] = {}
_cache_lock = threading.Lock()


def matrix_of(gallery: Gallery) -> GalleryMatrix:
    """The gallery's matrix, read again only when the gallery has changed since it was last read."""
    key = gallery.path.resolve()
    signature = gallery.signature()
    with _cache_lock:
        held = _cache.get(key)
    if held is not None and held.signature == signature:
        return held
    matrix = read_matrix(gallery)
    with _cache_lock:
        _cache.clear()  # one gallery at a time: a daemon has one
        _cache[key] = matrix
    return matrix
