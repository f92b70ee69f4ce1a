"""`POST /v1/reconstructions` over uploaded frames (`PUT /v1/imports/{folder}/{file}`): the result
is a scan like any other; refused inputs are answered at once, naming the field or file."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from rig.assembly import open_rig
from rig.patterns.described import described_patterns
from rig.patterns.spec import opencv_graycode
from rig.service.errors import ImportRefusedError
from rig.service.imports import store_file
from rig.service.job_service import JobService
from tests.conftest import wait_done
from tests.test_api import AUTH, _client, _service
from tests.test_reconstruct import _opencv_calibration


@pytest.fixture(scope="module")
def uploads(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Frames in OpenCV GrayCodePattern's convention from the small bench, and its true geometry as
    an OpenCV stereo calibration file."""
    folder = tmp_path_factory.mktemp("uploads")
    service = _service(folder / "render", start=False)
    with open_rig(service.config) as rig:
        width, height = service.config.projectors[0].resolution
        spec = opencv_graycode(width, height, "graycode_*.png")
        files = {}
        for i, pattern in enumerate(described_patterns(spec)):
            rig.projectors[0].show(pattern)
            _, png = cv2.imencode(".png", rig.cameras[0].capture().image)
            files[f"graycode_{i:02d}.png"] = png.tobytes()
        calibration = _opencv_calibration(folder / "cal.xml", rig.camera_models[0], rig.projector_models[0])
    files["calibration_result.xml"] = calibration.read_bytes()
    return {"files": files, "patterns": spec.model_dump(mode="json")}


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    service: JobService = _service(tmp_path)
    with _client(service) as c:
        yield c
    service.shutdown(5.0)


def _upload(client: TestClient, files: dict[str, bytes], folder: str = "board") -> None:
    for name, data in files.items():
        answer = client.put(f"/v1/imports/{folder}/{name}", content=data, headers=AUTH)
        assert answer.status_code == 201, answer.text
        assert answer.json()["bytes"] == len(data)


def test_uploaded_frames_reconstruct_into_a_scan(client: TestClient, uploads: dict[str, Any]) -> None:
    _upload(client, uploads["files"])
    listed = client.get("/v1/imports").json()
    count = len(uploads["files"])  # the frames of a 256x192 projector's codes, and the calibration
    assert listed == [{"folder": "board", "files": count, "bytes": sum(len(d) for d in uploads["files"].values())}]
    body = {"frames": "board", "patterns": uploads["patterns"], "calibration": "calibration_result.xml"}
    created = client.post("/v1/reconstructions", json=body, headers=AUTH)
    assert created.status_code == 202, created.text
    scan_id = created.json()["id"]
    assert created.headers["location"] == f"/v1/scans/{scan_id}"
    job = wait_done(client, scan_id)
    assert job["state"] == "done", job
    assert job["result"]["points"] > 10000
    manifest = json.loads(client.get(f"/v1/scans/{scan_id}/files/manifest.json").content)
    origin = manifest["origin"]["reconstructed"]
    assert origin["patterns"] == "inline" and len(origin["frames_sha256"]) == count - 1
    assert manifest["codec"]["name"] == "described"
    assert client.delete("/v1/imports/board", headers=AUTH).status_code == 204
    assert client.get("/v1/imports").json() == []


def test_refused_inputs_name_what_is_wrong_and_queue_nothing(client: TestClient, uploads: dict[str, Any]) -> None:
    frames = [name for name in uploads["files"] if name.endswith(".png")]
    files = {name: uploads["files"][name] for name in frames[:-1]}  # one frame short
    files["calibration_result.xml"] = uploads["files"]["calibration_result.xml"]
    _upload(client, files)
    base = {"frames": "board", "patterns": uploads["patterns"], "calibration": "calibration_result.xml"}
    cases: list[tuple[dict[str, Any], int, str]] = [
        (
            base,
            422,
            f"imports folder 'board': the pattern description has {len(frames)} frames (columns: 16 Gray; rows: 16 "
            f"Gray; white and black 2), {len(frames) - 1}",
        ),
        ({**base, "frames": "nothing"}, 404, "no imports folder 'nothing'"),
        ({**base, "calibration": "missing.xml"}, 404, "calibration: no file 'missing.xml'"),
        ({**base, "patterns": {**base["patterns"], "gray": {"axes": ["diagonal"]}}}, 422, "gray.axes"),
        ({**base, "calibration_options": {"world": "table"}}, 422, "calibration_options: world"),
        ({**base, "frames": "../etc"}, 422, "string_pattern_mismatch"),
    ]
    for body, code, message in cases:
        answer = client.post("/v1/reconstructions", json=body, headers=AUTH)
        assert answer.status_code == code, (body, answer.text)
        assert message in answer.text, (message, answer.text)
    assert client.get("/v1/scans").json()["total"] == 0
    assert client.post("/v1/reconstructions", json=base).status_code == 401  # the key, as for scans


def test_uploads_refuse_names_and_kinds_that_are_not_frames(client: TestClient, tmp_path: Path) -> None:
    refusals = {
        "/v1/imports/board/frame.exe": (422, "string_pattern_mismatch"),
        "/v1/imports/board/..png": (422, "string_pattern_mismatch"),
        "/v1/imports/board/.hidden.png": (422, "string_pattern_mismatch"),
        "/v1/imports/.board/frame.png": (422, "string_pattern_mismatch"),
        "/v1/imports/b%2F..%2Fx/frame.png": (422, "string_pattern_mismatch"),  # sub-folders are names too
    }
    for path, (code, message) in refusals.items():
        answer = client.put(path, content=b"x", headers=AUTH)
        assert answer.status_code == code, (path, answer.text)
        assert message in answer.text
    with pytest.raises(ImportRefusedError, match="suffix must be one of"):  # behind the path's own pattern
        store_file(tmp_path, "board", "frame.exe", b"x")
    assert client.put("/v1/imports/board/frame.png", content=b"x").status_code == 401


def test_only_the_keys_holder_may_send_a_large_upload(client: TestClient) -> None:
    """A body larger than the JSON limit (64 KiB) is held for an upload only when the key is valid:
    no one else makes the daemon buffer megabytes."""
    noise = np.random.default_rng(1).integers(0, 65535, (400, 400), dtype=np.uint16)
    frame = cv2.imencode(".png", noise)[1].tobytes()  # noise: a PNG of about 320 KB
    assert len(frame) > 65536
    assert client.put("/v1/imports/big/frame.png", content=frame).status_code == 413
    assert client.put("/v1/imports/big/frame.png", content=frame, headers={"X-API-Key": "x" * 32}).status_code == 413
    assert client.put("/v1/imports/big/frame.png", content=frame, headers=AUTH).status_code == 201
    assert client.delete("/v1/imports/big", headers=AUTH).status_code == 204
    assert client.delete("/v1/imports/big", headers=AUTH).status_code == 404


def test_a_calibration_split_over_two_uploaded_files(
    client: TestClient, uploads: dict[str, Any], tmp_path: Path
) -> None:
    from rig.calibrate.foreign import read_foreign_calibration

    (tmp_path / "cal.xml").write_bytes(uploads["files"]["calibration_result.xml"])
    found = read_foreign_calibration(tmp_path / "cal.xml")
    camera, projector = found.camera, found.projector
    halves = {
        "intrinsics.yml": {"M1": camera.K, "D1": camera.dist, "M2": projector.K, "D2": projector.dist},
        "extrinsics.yml": {"R": projector.R @ camera.R.T, "T": projector.t - projector.R @ camera.R.T @ camera.t},
    }
    files = {k: v for k, v in uploads["files"].items() if k.endswith(".png")}
    for name, fields in halves.items():
        storage = cv2.FileStorage(str(tmp_path / name), cv2.FILE_STORAGE_WRITE)
        for key, value in fields.items():
            storage.write(key, np.asarray(value, float))
        storage.release()
        files[name] = (tmp_path / name).read_bytes()
    _upload(client, files)
    sizes = {
        "camera_resolution": [camera.width, camera.height],
        "projector_resolution": [projector.width, projector.height],
    }
    body = {
        "frames": "board",
        "patterns": uploads["patterns"],
        "calibration": ["intrinsics.yml", "extrinsics.yml"],
        "calibration_options": sizes,
    }
    created = client.post("/v1/reconstructions", json=body, headers=AUTH)
    assert created.status_code == 202, created.text
    job = wait_done(client, created.json()["id"])
    assert job["state"] == "done", job
    assert job["result"]["points"] > 10000
    refused = client.post("/v1/reconstructions", json={**body, "calibration": []}, headers=AUTH)
    assert refused.status_code == 422 and "calibration" in refused.text
