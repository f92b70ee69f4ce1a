"""`POST /v1/calibrations` with `images`: a calibration from a folder of captures uploaded into
imports, one sub-folder per view (`PUT /v1/imports/{folder}/{view}/{file}`), in the bench's own
layout or another system's with a pattern description. It gives what `slrig calibrate --images`
gives on the same files; refused inputs are answered at once, naming the field."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from fastapi.testclient import TestClient

from rig.cli import main
from rig.service.job_service import JobService
from tests.conftest import shared_data, wait_done
from tests.test_api import AUTH, _client, _service
from tests.test_calibrate_described import PROCAM


@pytest.fixture(scope="module")
def saved_views(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Four views of the small bench (board, and the projector's calibration patterns) as
    `slrig calibrate rig --save-views` writes them, and the CLI's calibration from that folder."""
    folder = tmp_path_factory.mktemp("views")
    config = _service(folder / "bench", start=False).config
    path = folder / "bench" / "serve.yaml"
    views, out = folder / "views", folder / "cli"
    common = ["--config", str(path), "--json"]
    assert (
        main(["calibrate", "rig", *common, "--views", "4", "--out", str(folder / "first"), "--save-views", str(views)])
        == 0
    )
    assert main(["calibrate", "rig", *common, "--images", str(views), "--out", str(out)]) == 0
    files = {str(p.relative_to(views)): p.read_bytes() for p in sorted(views.rglob("*.png"))}
    return {"files": files, "cli": json.loads((out / "calibration.json").read_text()), "config": config}


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    service: JobService = _service(tmp_path)
    with _client(service) as c:
        yield c
    service.shutdown(5.0)


def _upload(client: TestClient, folder: str, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        answer = client.put(f"/v1/imports/{folder}/{name}", content=data, headers=AUTH)
        assert answer.status_code == 201, answer.text


def _devices(document: dict[str, Any]) -> dict[str, np.ndarray]:
    return {d["name"]: np.array(d["K"]) for d in document["devices"]}


def test_uploaded_views_calibrate_the_rig_as_the_command_line_does(
    client: TestClient, saved_views: dict[str, Any]
) -> None:
    files = saved_views["files"]
    assert any(name.count("/") == 2 for name in files)  # view_NN/<projector>_<camera>/NNN.png
    _upload(client, "bench", files)
    assert client.get("/v1/imports").json() == [
        {"folder": "bench", "files": len(files), "bytes": sum(len(d) for d in files.values())}
    ]
    created = client.post("/v1/calibrations", json={"what": "rig", "images": "bench"}, headers=AUTH)
    assert created.status_code == 202, created.text
    job = wait_done(client, created.json()["id"], "calibrations", timeout_s=300)
    assert job["state"] == "done", job
    assert job["result"]["views"] == 4
    assert {"view_00_camera0.jpg", "residuals_projector0.png", "calibration.json"} <= set(job["result"]["files"])
    document = json.loads(client.get(f"/v1/calibrations/{job['id']}/files/calibration.json").content)
    ours, theirs = _devices(document), _devices(saved_views["cli"])
    assert set(ours) == {"camera0", "projector0"} == set(theirs)
    for name in ours:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=1e-6)  # the same solve; OpenCV's threads reorder sums
    # the views came from files: the rig was never opened, and a scan can use the result at once
    assert client.get("/v1/rig").json().get("error") is None


def test_refused_calibration_requests_name_the_field(client: TestClient, saved_views: dict[str, Any]) -> None:
    some = dict(list(saved_views["files"].items())[:3])
    _upload(client, "bench", some)
    _upload(client, "flat", {"camera0.png": next(iter(some.values()))})
    refusals: list[tuple[dict[str, Any], int, str]] = [
        ({"images": "nowhere"}, 404, "no imports folder 'nowhere'"),
        ({"images": None}, 422, "images: null; leave it out"),
        ({"images": "flat"}, 422, "images: imports folder 'flat' has no view_NN sub-folders"),
        ({"images": "../bench"}, 422, "images"),
        ({"patterns": {"frames": {"files": "*.png"}}}, 422, "patterns: only with images"),
        ({"images": "bench", "view_glob": "capture_*"}, 422, "view_glob: only with patterns"),
        ({"images": "bench", "views": 5}, 422, "views: the captures in images are the views"),
        ({"what": "response", "images": "bench"}, 422, "a response measurement projects its own patterns"),
        ({"images": "bench", "board": "checker:10x8"}, 422, "board: 'checker:10x8' is not KIND:COLSxROWS"),
        ({"images": "bench", "model": "k9"}, 422, "model"),
        ({"images": "bench", "patterns": "missing.yaml"}, 404, "patterns: no file 'missing.yaml'"),
        ({"images": "bench", "patterns": {"frames": {"files": "*.png"}}}, 422, "patterns"),
        ({"images": "bench", "patterns": {**PROCAM}, "view_glob": "capture_*"}, 422, "no sub-folders matching"),
    ]
    for body, status, message in refusals:
        answer = client.post("/v1/calibrations", json={"what": "rig", **body}, headers=AUTH)
        assert answer.status_code == status, (body, answer.text)
        assert message in answer.text, (body, answer.text)
    assert client.get("/v1/calibrations").json()["total"] == 0  # nothing was queued


def test_nested_upload_paths_are_bounded(client: TestClient) -> None:
    png = bytes.fromhex("89504e470d0a1a0a")  # refused by its header, if a path were taken
    for name, status in (
        ("a/b/c/d.png", 422),  # three sub-folders: one too many
        ("a/../b.png", 422),
        ("a//b.png", 422),
        (".hidden/b.png", 422),
        ("a/b.exe", 422),
    ):
        answer = client.put(f"/v1/imports/deep/{name}", content=png, headers=AUTH)
        assert answer.status_code in (status, 404), (name, answer.text)
    good = client.put("/v1/imports/deep/view_00/camera0.yaml", content=b"a: 1\n", headers=AUTH)
    assert good.status_code == 201, good.text
    assert good.headers["location"] == "/v1/imports/deep/view_00/camera0.yaml"
    clash = client.put("/v1/imports/deep/view_00", content=b"a: 1\n", headers=AUTH)
    assert clash.status_code == 422  # no suffix: never a file where a folder is
    clash = client.put("/v1/imports/deep/view_00/camera0.yaml/x.yaml", content=b"a: 1\n", headers=AUTH)
    assert clash.status_code == 422 and "a file of the name of one of its folders" in clash.text
    assert client.get("/v1/imports").json() == [{"folder": "deep", "files": 1, "bytes": 5}]


def test_another_systems_captures_calibrate_over_rest(client: TestClient, tmp_path: Path) -> None:
    sample = shared_data("procam-calibration", "sample_data")
    files = {
        f"{view.name}/{frame.name}": frame.read_bytes()
        for view in sorted(sample.glob("capture_[0-2]"))
        for frame in sorted(view.glob("graycode_*.png"))
    }
    files["procam.yaml"] = yaml.safe_dump(PROCAM).encode()
    _upload(client, "procam", files)
    body = {
        "what": "rig",
        "images": "procam",
        "patterns": "procam.yaml",
        "view_glob": "capture_*",
        "board": "checker:10x8:75",
    }
    created = client.post("/v1/calibrations", json=body, headers=AUTH)
    assert created.status_code == 202, created.text
    job = wait_done(client, created.json()["id"], "calibrations", timeout_s=300)
    assert job["state"] == "done", job
    out = tmp_path / "cli"
    described = tmp_path / "procam.yaml"
    described.write_text(yaml.safe_dump(PROCAM))
    views = tmp_path / "views"
    for name, data in files.items():
        if "/" in name:
            (views / name).parent.mkdir(parents=True, exist_ok=True)
            (views / name).write_bytes(data)
    args = ["calibrate", "rig", "--images", str(views), "--patterns", str(described), "--view-glob", "capture_*"]
    assert main([*args, "--board", "checker:10x8:75", "--out", str(out)]) == 0
    document = json.loads(client.get(f"/v1/calibrations/{job['id']}/files/calibration.json").content)
    ours, theirs = _devices(document), _devices(json.loads((out / "calibration.json").read_text()))
    for name in theirs:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=1e-6)  # the same solve; OpenCV's threads reorder sums
