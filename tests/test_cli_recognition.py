"""`slrig gallery add|list|remove` and `slrig identify` on ring scans of the default bench."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from rig.cli import main


@pytest.fixture(scope="module")
def scans(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """One ring scan, added and identified (the REST tests identify a second scan of the object)."""
    target = tmp_path_factory.mktemp("cli-recognition") / "scan"
    assert main(["scan", "--codec", "rings", "--out", str(target), "--json"]) == 0
    return [target, target]


def test_add_list_identify_and_remove(scans: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gallery = ["--gallery", str(tmp_path / "g.db")]
    assert main(["identify", str(scans[1]), *gallery]) == 2
    assert "the gallery is empty" in capsys.readouterr().err
    assert main(["gallery", "add", str(scans[0]), "--label", "two words", *gallery]) == 2
    assert "not a plain name" in capsys.readouterr().err and not (tmp_path / "g.db").exists()
    assert main(["gallery", "add", str(scans[0]), "--label", "sphere", "--outer-mm", "40", "--json", *gallery]) == 0
    entry = json.loads(capsys.readouterr().out)
    assert entry["label"] == "sphere" and entry["settings"]["outer_mm"] == 40
    assert main(["gallery", "add", str(scans[0]), "--label", "again", *gallery]) == 2
    assert "is in the gallery already" in capsys.readouterr().err
    assert main(["gallery", "list", "--json", *gallery]) == 0
    assert [e["scan_id"] for e in json.loads(capsys.readouterr().out)["entries"]] == [entry["scan_id"]]
    assert main(["identify", str(scans[1]), "--json", *gallery]) == 0
    found = json.loads(capsys.readouterr().out)
    assert found["label"] == "sphere" and found["matches"][0]["entry_id"] == entry["id"]
    assert main(["identify", str(scans[1]), *gallery]) == 0
    said = capsys.readouterr().out.splitlines()
    told = re.search(r"sphere: scores (\S+), at or above the threshold (\S+) \((\w+) comparison", said[0])
    assert told is not None, said[0]
    score, threshold, comparison = told.groups()
    assert score != threshold  # printed with the digits that tell them apart (0.9998 is not 1.000)
    assert float(threshold) == pytest.approx(found["threshold"], abs=1e-4) and comparison == found["comparison"]
    assert main(["identify", str(scans[1]), "--threshold", "2", *gallery]) == 2
    assert "--threshold" in capsys.readouterr().err
    assert main(["gallery", "remove", str(entry["id"]), *gallery]) == 0
    assert main(["gallery", "remove", str(entry["id"]), *gallery]) == 2
    assert "no gallery entry" in capsys.readouterr().err


def test_a_file_that_is_not_a_gallery_is_refused_and_kept(scans: list[Path], tmp_path: Path) -> None:
    path = tmp_path / "notes.db"
    path.write_text("my notes, not a gallery")
    assert main(["gallery", "add", str(scans[0]), "--label", "a", "--gallery", str(path)]) == 2
    assert path.read_text() == "my notes, not a gallery"
    assert main(["identify", str(tmp_path), "--gallery", str(path)]) == 2


def test_an_unknown_says_why_with_the_digits_that_tell_score_and_threshold_apart() -> None:
    from rig.cli.recognising import verdict
    from rig.recognition.identify import Identification, Match

    found = Identification("unknown", [Match("face", 0.99996, 3, "s1"), Match("box", 0.2, 4, "s2")], 0.99998, "raw")
    assert verdict(found) == (
        "unknown: the best match, face, scores +0.99996, below the threshold +0.99998 "
        "(raw comparison; --threshold sets another)"
    )
