"""`slrig gallery add|list|remove` and `slrig identify` on ring scans of the default bench."""

from __future__ import annotations

import json
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
