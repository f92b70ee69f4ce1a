"""Uploads within limits: a required body, a size per file and per imports folder, free space kept
for the job records (507 before anything is written), and images judged by their headers before
any decoding (a decompression bomb is refused, never decoded)."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from rig.service import space
from rig.service.job_service import JobService
from rig.service.space import RESERVE_BYTES
from tests.bombs import write_png_bomb
from tests.test_api import AUTH, _client, _service


def _png(width: int = 64, height: int = 48) -> bytes:
    return cv2.imencode(".png", np.full((height, width), 128, np.uint8))[1].tobytes()


@pytest.fixture
def uploads(tmp_path: Path) -> Iterator[tuple[JobService, TestClient]]:
    service = _service(tmp_path, start=False, max_import_bytes=1024**2, max_image_pixels=1_000_000)
    service.data_dir.mkdir(parents=True, exist_ok=True)
    with _client(service) as client:
        yield service, client
    service.store.close()


def _stored(service: JobService, folder: str) -> list[str]:
    path = service.data_dir / "imports" / folder
    return sorted(p.name for p in path.iterdir()) if path.is_dir() else []


def test_a_body_is_required(uploads: tuple[JobService, TestClient]) -> None:
    service, client = uploads
    for headers in ({}, {"Content-Length": "0"}):
        answer = client.put("/v1/imports/f/frame_00.png", content=b"", headers={**AUTH, **headers})
        assert answer.status_code == 422 and "empty" in answer.text
    assert _stored(service, "f") == []


def test_an_imports_folder_has_a_size_limit(uploads: tuple[JobService, TestClient]) -> None:
    service, client = uploads
    part = b"x" * 400_000  # descriptions are not images: only the size counts
    assert client.put("/v1/imports/f/a.yaml", content=part, headers=AUTH).status_code == 201
    assert client.put("/v1/imports/f/b.yaml", content=part, headers=AUTH).status_code == 201
    refused = client.put("/v1/imports/f/c.yaml", content=part, headers=AUTH)
    assert refused.status_code == 413 and "max_import_bytes" in refused.text
    assert client.put("/v1/imports/f/b.yaml", content=part, headers=AUTH).status_code == 201  # replacing: same size
    assert _stored(service, "f") == ["a.yaml", "b.yaml"]


def test_an_image_over_the_pixel_limit_is_refused_from_its_header(
    uploads: tuple[JobService, TestClient], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    service, client = uploads
    bomb = tmp_path / "bomb.png"
    write_png_bomb(bomb, 20000, 20000)  # 800 MB of pixels in 0.78 MB
    decoded: list[int] = []
    real_decode = cv2.imdecode
    monkeypatch.setattr(cv2, "imdecode", lambda *a, **k: decoded.append(1) or real_decode(*a, **k))
    refused = client.put("/v1/imports/f/frame_00.png", content=bomb.read_bytes(), headers=AUTH)
    assert refused.status_code == 422 and "20000x20000" in refused.text and "frame_00.png" in refused.text
    garbage = client.put("/v1/imports/f/frame_01.png", content=b"not a png at all", headers=AUTH)
    assert garbage.status_code == 422 and "frame_01.png" in garbage.text
    assert client.put("/v1/imports/f/frame_02.png", content=_png(), headers=AUTH).status_code == 201
    assert decoded == [] and _stored(service, "f") == ["frame_02.png"]


def test_free_space_is_checked_before_the_body_is_read_and_the_reserve_kept(
    uploads: tuple[JobService, TestClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    service, client = uploads
    real = shutil.disk_usage(service.data_dir)
    free = RESERVE_BYTES + 100_000  # the disk as it would be nearly full: room for 100 kB beyond the reserve
    monkeypatch.setattr(space.shutil, "disk_usage", lambda path: real._replace(free=free))
    assert client.put("/v1/imports/f/small.yaml", content=b"y" * 50_000, headers=AUTH).status_code == 201
    refused = client.put("/v1/imports/f/large.yaml", content=b"y" * 200_000, headers=AUTH)
    assert refused.status_code == 507 and "stay free for the job records" in refused.text
    chunked = client.put("/v1/imports/f/streamed.yaml", content=iter([b"y" * 100_000, b"y" * 100_000]), headers=AUTH)
    assert chunked.status_code == 507  # no declared length: judged once the body is in, before writing
    assert _stored(service, "f") == ["small.yaml"]


def test_without_the_key_an_upload_is_refused_before_anything_is_judged(
    uploads: tuple[JobService, TestClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, client = uploads
    real = shutil.disk_usage(client.app.state.service.data_dir)  # type: ignore[attr-defined]
    monkeypatch.setattr(space.shutil, "disk_usage", lambda path: real._replace(free=RESERVE_BYTES // 2))
    for body in (b"", b"y" * 1000):  # not 422 (empty) nor 507 (full): nothing is told without the key
        assert client.put("/v1/imports/f/a.yaml", content=body).status_code == 401
        assert client.put("/v1/imports/f/a.yaml", content=body, headers={"X-API-Key": "x" * 32}).status_code == 403


def test_concurrent_uploads_cannot_pass_a_limit_together(tmp_path: Path) -> None:
    from concurrent.futures import ThreadPoolExecutor

    from rig.errors import SlrigError
    from rig.service.imports import store_file

    def upload(k: int) -> bool:
        try:
            store_file(tmp_path, "f", f"part{k}.yaml", b"z" * 1_000_000, max_folder_bytes=2_500_000)
        except SlrigError:
            return False
        return True

    with ThreadPoolExecutor(8) as pool:
        stored = list(pool.map(upload, range(8)))
    assert sum(stored) == 2 and len(list((tmp_path / "imports" / "f").iterdir())) == 2
