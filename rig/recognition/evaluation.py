"""How well a descriptor recognises: rank-1 identification and the equal error rate of
verification, from a matrix of scores (probes x gallery entries, higher is more alike)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Verification:
    """The equal error rate: where the fraction of impostors accepted (score >= threshold) equals
    the fraction of genuine probes rejected."""

    equal_error_rate: float
    threshold: float


def rank_one(scores: np.ndarray, probe_labels: Sequence[str], gallery_labels: Sequence[str]) -> np.ndarray:
    """(P,) whether each probe's best-scoring gallery entry carries its own label."""
    if scores.shape != (len(probe_labels), len(gallery_labels)):
        shape = (len(probe_labels), len(gallery_labels))
        raise ValueError(f"scores {scores.shape} do not match {shape[0]} probes x {shape[1]} gallery entries")
    best = np.asarray(gallery_labels)[np.argmax(scores, axis=1)]
    return best == np.asarray(probe_labels)


def genuine_and_impostor(
    scores: np.ndarray, probe_labels: Sequence[str], gallery_labels: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """The scores of probes against entries of their own label, and against all others."""
    same = np.asarray(probe_labels)[:, None] == np.asarray(gallery_labels)[None, :]
    return scores[same], scores[~same]


def equal_error_rate(genuine: np.ndarray, impostor: np.ndarray) -> Verification:
    """The equal error rate over every threshold between the scores, interpolated linearly between
    the two thresholds where false acceptance and false rejection cross."""
    if len(genuine) == 0 or len(impostor) == 0:
        raise ValueError("the equal error rate needs genuine and impostor scores")
    if genuine.min() > impostor.max():  # apart: no error at any threshold between them
        return Verification(0.0, float(genuine.min() + impostor.max()) / 2.0)
    thresholds = np.unique(np.concatenate([genuine, impostor]))
    thresholds = np.concatenate([thresholds, [np.nextafter(thresholds[-1], np.inf)]])
    genuine, impostor = np.sort(genuine), np.sort(impostor)
    rejected = np.searchsorted(genuine, thresholds, side="left") / len(genuine)  # genuine below the threshold
    accepted = 1.0 - np.searchsorted(impostor, thresholds, side="left") / len(impostor)  # impostors at or above
    gap = accepted - rejected  # falls from 1 (lowest threshold) to -1 (above every score)
    after = int(np.argmax(gap <= 0.0))
    before = after - 1
    share = gap[before] / (gap[before] - gap[after])
    rate = rejected[before] + share * (rejected[after] - rejected[before])
    threshold = thresholds[before] + share * (thresholds[after] - thresholds[before])
    return Verification(float(rate), float(threshold))
