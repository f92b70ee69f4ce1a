"""`slrig store migrate OLD NEW`: a data directory moved whole, its job records and scans served
from the new place; refused, with nothing moved, where that would lose or mix anything."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.cli import main
from rig.config import load_config
from rig.service.job_service import JobService
from tests.conftest import small_config_data, wait_done, write_config
from tests.test_api import AUTH, _client, _service


def _store_with_a_scan(root: Path) -> tuple[Path, str]:
    """A daemon's data directory (under `root`/serve) holding one finished scan."""
    service = _service(root)
    try:
        with _client(service) as client:
            job = client.post("/v1/scans", json={"codec": "gray"}, headers=AUTH).json()
            assert wait_done(client, job["id"])["state"] == "done"
    finally:
        service.shutdown(5.0)
    return service.data_dir, job["id"]


def _serving(folder: Path, data_dir: Path) -> JobService:
    """A started job service of the small bench on `data_dir`."""
    folder.mkdir(parents=True, exist_ok=True)
    data = small_config_data()
    data["output"] = {"data_dir": str(data_dir)}
    service = JobService(load_config(write_config(folder, data, "serve.yaml")))
    service.start()
    return service


def test_a_moved_store_serves_its_scans_from_the_new_place(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    old, scan_id = _store_with_a_scan(tmp_path / "before")
    cloud = (old / "scans" / scan_id / "cloud.ply").read_bytes()
    new = tmp_path / "elsewhere" / "slrig-data"
    assert main(["store", "migrate", str(old), str(new), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == {"from": str(old), "to": str(new), "scans": 1, "calibrations": 0}
    assert not old.exists() and (new / "scans" / scan_id / "cloud.ply").read_bytes() == cloud
    moved = _serving(tmp_path / "after", new)
    try:
        with _client(moved) as client:
            assert client.get(f"/v1/scans/{scan_id}").json()["state"] == "done"
            assert client.get(f"/v1/scans/{scan_id}/files/cloud.ply").content == cloud
    finally:
        moved.shutdown(5.0)


def test_a_move_that_could_lose_or_mix_anything_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    old, scan_id = _store_with_a_scan(tmp_path / "before")
    occupied = tmp_path / "occupied"
    occupied.mkdir()
    (occupied / "mine.txt").write_text("keep")
    plain = tmp_path / "plain"
    plain.mkdir()
    refusals = {
        (str(plain), str(tmp_path / "x")): "not a slrig data directory",
        (str(old), str(occupied)): "exists already",
        (str(old), str(old / "inner")): "inside",
    }
    for (source, target), message in refusals.items():
        assert main(["store", "migrate", source, target]) == 2
        assert message in capsys.readouterr().err
    held = _serving(tmp_path / "serving", old)  # a daemon holds the old directory
    try:
        assert main(["store", "migrate", str(old), str(tmp_path / "new")]) == 2
        assert "another slrig daemon is using" in capsys.readouterr().err
    finally:
        held.shutdown(5.0)
    assert (old / "scans" / scan_id / "cloud.ply").is_file() and not (tmp_path / "new").exists()
    assert (occupied / "mine.txt").read_text() == "keep" and sorted(p.name for p in occupied.iterdir()) == ["mine.txt"]
