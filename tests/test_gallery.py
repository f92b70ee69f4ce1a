"""The recognition gallery (SQLite) and identification: what it refuses, what it never overwrites,
and how it ranks."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest

from rig.errors import GalleryError, RecognitionError
from rig.recognition.descriptor import Descriptor, DescriptorSettings
from rig.recognition.gallery import Gallery
from rig.recognition.identify import UNKNOWN, identify, scores


def _descriptor(features: np.ndarray, settings: DescriptorSettings | None = None) -> Descriptor:
    settings = settings or DescriptorSettings(rings=2, samples=8)
    distances = np.zeros((settings.rings, settings.samples))
    return Descriptor(features, distances, np.zeros(3), np.array([0.0, 0.0, 1.0]), settings)


def _features(seed: int, size: int = 10) -> np.ndarray:
    return np.random.default_rng(seed).uniform(1.0, 2.0, size)


def test_entries_survive_reopening_and_keep_their_scan_and_settings(tmp_path: Path) -> None:
    path = tmp_path / "gallery.db"
    with Gallery(path) as gallery:
        first = gallery.add("alice", "scan-a", _descriptor(_features(1)))
        gallery.add("bob", "scan-b", _descriptor(_features(2)))
    with Gallery(path) as gallery:
        entries, matrix = gallery.features()
        assert [(e.label, e.scan_id) for e in entries] == [("alice", "scan-a"), ("bob", "scan-b")]
        assert np.array_equal(matrix[0], _features(1))
        assert gallery.settings() == DescriptorSettings(rings=2, samples=8)
        assert gallery.remove(first.id).label == "alice"
        assert [e.label for e in gallery.entries()] == ["bob"]
        with pytest.raises(GalleryError, match="no gallery entry"):
            gallery.remove(first.id)


@pytest.mark.parametrize("label", ["", "two words", "../etc", "a" * 65, "-dash-first", "naïve"])
def test_a_label_that_is_not_a_plain_name_is_refused_and_nothing_is_written(tmp_path: Path, label: str) -> None:
    path = tmp_path / "gallery.db"
    with Gallery(path) as gallery, pytest.raises(GalleryError, match="not a plain name"):
        gallery.add(label, "scan-a", _descriptor(_features(1)))
    assert not path.exists()


def test_a_duplicate_scan_and_other_settings_are_refused(tmp_path: Path) -> None:
    with Gallery(tmp_path / "gallery.db") as gallery:
        gallery.add("alice", "scan-a", _descriptor(_features(1)))
        with pytest.raises(GalleryError, match="scan-a is in the gallery already"):
            gallery.add("carol", "scan-a", _descriptor(_features(3)))
        other = DescriptorSettings(rings=2, samples=8, distance="euclidean")
        with pytest.raises(GalleryError, match="distance 'euclidean' \\(gallery: 'geodesic'\\)"):
            gallery.add("bob", "scan-b", _descriptor(_features(2), other))
        assert len(gallery.entries()) == 1


def test_a_file_that_is_not_a_gallery_or_a_newer_one_is_refused_and_left_as_it_is(tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"\x00not a database" * 100)
    newer = tmp_path / "newer.db"
    with Gallery(newer) as gallery:
        gallery.add("alice", "scan-a", _descriptor(_features(1)))
    db = sqlite3.connect(newer)
    db.execute("PRAGMA user_version = 2")
    db.close()
    other = tmp_path / "other.db"
    db = sqlite3.connect(other)
    db.execute("CREATE TABLE jobs (id TEXT)")
    db.close()
    for path, reason in ((junk, "not an SQLite database"), (newer, "newer slrig"), (other, "no entries table")):
        before = path.read_bytes()
        with pytest.raises(GalleryError, match=reason):
            Gallery(path)
        assert path.read_bytes() == before


def test_identification_ranks_labels_by_their_best_entry_and_says_unknown_below_the_threshold(tmp_path: Path) -> None:
    with Gallery(tmp_path / "gallery.db") as gallery:
        for i, label in enumerate(["alice", "bob", "carol", "alice"]):
            gallery.add(label, f"scan-{i}", _descriptor(_features(i)))
        entries, matrix = gallery.features()
    probe = _features(3) + np.random.default_rng(9).normal(0, 0.01, 10)  # near alice's second entry
    found = identify(probe, entries, matrix, top=2, threshold=0.5)
    assert found.label == "alice" and found.matches[0].scan_id == "scan-3"
    assert [m.label for m in found.matches] == ["alice", found.matches[1].label] and len(found.matches) == 2
    assert identify(probe, entries, matrix, threshold=1.01).label == UNKNOWN
    with pytest.raises(RecognitionError, match="the gallery is empty"):
        identify(probe, [], np.zeros((0, 0)))


def test_standardising_removes_what_every_entry_shares() -> None:
    rng = np.random.default_rng(0)
    shared = np.linspace(100.0, 1.0, 40)  # what every surface of a kind has: raw correlations near 1
    gallery = shared + rng.normal(0, 1.0, (6, 40))
    probe = gallery[2] + rng.normal(0, 0.3, 40)
    raw = scores(probe, gallery, "raw")
    standardised = scores(probe, gallery, "standardised")
    assert raw.min() > 0.99  # raw: everything looks alike
    assert np.argmax(standardised) == 2 and np.sort(standardised)[-2] < 0.5 < standardised[2]


def test_features_the_gallery_barely_varies_do_not_outweigh_the_shape() -> None:
    # 30 features that tell the entries apart, 10 that the gallery happens to hold almost constant
    # (a high harmonic of a smooth ring) and that a probe's scan noise moves: divided by their own
    # tiny spread they would decide the match on noise alone
    rng = np.random.default_rng(4)
    shape = rng.normal(0, 1.0, (10, 30))
    quiet = 5.0 + rng.normal(0, 0.01, (10, 10))
    gallery = np.hstack([shape, quiet])
    wins = 0
    for trial in range(20):
        target = trial % 10
        probe = gallery[target] + np.concatenate([rng.normal(0, 0.3, 30), rng.normal(0, 0.1, 10)])
        wins += int(np.argmax(scores(probe, gallery, "standardised")) == target)
    assert wins >= 19  # divided by the plain spread: 8 of 20


def test_a_gallery_too_small_to_standardise_is_compared_raw_against_the_raw_threshold(tmp_path: Path) -> None:
    with Gallery(tmp_path / "gallery.db") as gallery:
        for i, label in enumerate(["alice", "bob"]):
            gallery.add(label, f"scan-{i}", _descriptor(_features(i)))
        entries, matrix = gallery.features()
    probe = _features(1) + np.random.default_rng(9).normal(0, 0.01, 10)
    thresholds = {"standardised": 0.999, "raw": 0.9}
    found = identify(probe, entries, matrix, threshold=thresholds)  # type: ignore[arg-type]
    assert found.comparison == "raw" and found.threshold == 0.9 and found.label == "bob"
    assert found.matches[0].score == pytest.approx(scores(probe, matrix, "raw")[1])


@pytest.mark.parametrize("comparison", ["standardised", "raw"])
def test_the_prepared_matrix_identifies_as_the_gallery_does_and_follows_its_changes(
    tmp_path: Path, comparison: str
) -> None:
    from rig.recognition.matrix import matrix_of

    rng = np.random.default_rng(7)
    shared = rng.uniform(1.0, 2.0, 10)
    with Gallery(tmp_path / "gallery.db") as gallery:
        for n in range(40):  # 8 labels of 5 entries, each a label's shape plus noise
            label = f"label-{n % 8}"
            features = shared + 0.3 * np.random.default_rng(n % 8).normal(size=10) + 0.02 * rng.normal(size=10)
            gallery.add(label, f"scan-{n}", _descriptor(features))
        entries, features = gallery.features()
        probe = features[13] + 0.01 * rng.normal(size=10)
        matrix = matrix_of(gallery)
        np.testing.assert_allclose(matrix.scores(probe, comparison), scores(probe, features, comparison), atol=1e-12)
        expected = identify(probe, entries, features, top=5, comparison=comparison)
        found = matrix.identify(probe, top=5, comparison=comparison)
        assert found.label == expected.label == "label-5"
        assert [(m.label, m.entry_id, m.scan_id) for m in found.matches] == [
            (m.label, m.entry_id, m.scan_id) for m in expected.matches
        ]
        assert matrix_of(gallery) is matrix  # unchanged: not read again
        gallery.add("label-new", "scan-new", _descriptor(probe))
        again = matrix_of(gallery)
        assert again is not matrix and again.identify(probe, comparison=comparison).label == "label-new"


def test_many_entries_are_added_all_together_or_not_at_all(tmp_path: Path) -> None:
    with Gallery(tmp_path / "gallery.db") as gallery:
        gallery.add("alice", "scan-a", _descriptor(_features(1)))
        batch = [("bob", "scan-b", _descriptor(_features(2))), ("carol", "scan-a", _descriptor(_features(3)))]
        with pytest.raises(GalleryError, match="scan-a is in the gallery already \\(label 'alice'\\)"):
            gallery.add_many(batch)
        assert [e.scan_id for e in gallery.entries()] == ["scan-a"]  # bob went back out with carol
        added = gallery.add_many([batch[0], ("carol", "scan-c", _descriptor(_features(3)))])
        assert [(e.label, e.scan_id) for e in added] == [("bob", "scan-b"), ("carol", "scan-c")]
        assert [e.id for e in added] == [e.id for e in gallery.entries()[1:]]
