"""Recognition measured: rank-1, the equal error rate, and the eigen-depth baseline."""

from __future__ import annotations

import numpy as np
import pytest

from rig.errors import RecognitionError
from rig.recognition.eigendepth import EigenDepth, depth_map
from rig.recognition.evaluation import equal_error_rate, genuine_and_impostor, rank_one


def test_rank_one_counts_a_probe_right_when_its_best_entry_has_its_label() -> None:
    score = np.array([[0.9, 0.1, 0.2], [0.3, 0.2, 0.8], [0.1, 0.7, 0.6]])
    hit = rank_one(score, ["a", "b", "c"], ["a", "b", "c"])
    assert hit.tolist() == [True, False, False]
    genuine, impostor = genuine_and_impostor(score, ["a", "b", "c"], ["a", "b", "c"])
    assert sorted(genuine.tolist()) == [0.2, 0.6, 0.9] and len(impostor) == 6
    with pytest.raises(ValueError, match="do not match"):
        rank_one(score, ["a", "b"], ["a", "b", "c"])


def test_the_equal_error_rate_of_overlapping_uniform_scores() -> None:
    """Genuine scores even on [0.4, 1], impostors on [0, 0.6]: the rates cross at 0.5, where a
    sixth of each is on the wrong side."""
    genuine, impostor = np.linspace(0.4, 1.0, 6001), np.linspace(0.0, 0.6, 6001)
    found = equal_error_rate(genuine, impostor)
    assert found.equal_error_rate == pytest.approx(1 / 6, abs=1e-3)
    assert found.threshold == pytest.approx(0.5, abs=1e-3)
    apart = equal_error_rate(np.array([0.8, 0.9]), np.array([0.1, 0.4]))
    assert apart.equal_error_rate == 0.0 and apart.threshold == pytest.approx(0.6)
    with pytest.raises(ValueError, match="genuine and impostor"):
        equal_error_rate(np.array([]), impostor)


def _dome(seed: int, noise_seed: int) -> np.ndarray:
    """A dome 30 mm high with random bumps, sampled from above with noise."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(-60.0, 60.0, 0.5), np.arange(-60.0, 60.0, 0.5))
    z = 30.0 * np.exp(-(x**2 + y**2) / (2 * 25.0**2))
    for cx, cy, height in zip(*rng.uniform(-35, 35, (2, 6)), rng.uniform(-4, 4, 6), strict=True):
        z += height * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 8.0**2))
    points = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    return points + np.random.default_rng(noise_seed).normal(0.0, 0.05, points.shape)


def test_eigen_depth_finds_each_object_again_from_a_new_scan_of_it() -> None:
    up, centre = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 30.0])
    gallery = np.array([depth_map(_dome(seed, 0), centre, up, 48.0) for seed in range(6)])
    probes = np.array([depth_map(_dome(seed, 1), centre, up, 48.0) for seed in range(6)])
    model = EigenDepth.fit(gallery)
    assert 1 <= len(model.spread) <= 5
    similarity = model.similarity(probes, gallery)
    assert np.argmax(similarity, axis=1).tolist() == list(range(6))
    assert np.diag(similarity).min() > 0.99
    with pytest.raises(RecognitionError, match="at least two"):
        EigenDepth.fit(gallery[:1])
    with pytest.raises(RecognitionError, match="too little surface for a depth map"):
        depth_map(_dome(0, 0)[:500], centre, up, 48.0)
