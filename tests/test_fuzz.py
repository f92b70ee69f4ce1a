"""Property-based fuzzing (Hypothesis) of what slrig reads from outside: rig configs, mesh files and
request bodies. Each must be accepted or refused with the field named (ConfigError / ValueError /
a 4xx) and never end in a traceback, a 500 or unbounded memory.

The run in CI is short and repeatable (a fixed example budget, derandomized); set
SLRIG_FUZZ_EXAMPLES=2000 (or more) for a long run.
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
import yaml
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.sim.scene import mesh_file
from rig.api.models import (
    CalibrationRequest,
    GalleryAddRequest,
    IdentifyRequest,
    ReconstructionRequest,
    ReprocessRequest,
    ScanRequest,
)
from rig.config import load_config
from rig.errors import ConfigError
from tests.conftest import small_config_data
from tests.test_api import AUTH, _client, _service

EXAMPLES = int(os.environ.get("SLRIG_FUZZ_EXAMPLES", "40"))
FUZZ = settings(
    max_examples=EXAMPLES,
    derandomize=True,  # the same examples every run: CI is repeatable
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

# --- configs -----------------------------------------------------------------------------------


def _leaves(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    if isinstance(data, dict):
        yield path
        for key, value in data.items():
            yield from _leaves(value, (*path, key))
    elif isinstance(data, list):
        yield path
        for index, value in enumerate(data):
            yield from _leaves(value, (*path, index))
    else:
        yield path


BASE = small_config_data()
PATHS = [p for p in _leaves(BASE) if p]
SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=40),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=4),
    max_leaves=12,
)
KEYS = st.one_of(st.text(min_size=1, max_size=20), st.sampled_from(["my-key", "capture-timeout-s", "1x", "ü", " "]))


def _parent(data: Any, path: tuple[Any, ...]) -> Any:
    """The container of `path`'s last step, or None where an earlier mutation replaced the way."""
    for key in path[:-1]:
        try:
            data = data[key]
        except (KeyError, IndexError, TypeError):
            return None
    return data if isinstance(data, (dict, list)) else None


@st.composite
def mutated_configs(draw: st.DrawFn) -> bytes:
    data = json.loads(json.dumps(BASE))
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS))
        parent = _parent(data, path)
        if parent is None:
            continue
        if draw(st.booleans()):
            if isinstance(parent, dict) or path[-1] < len(parent):
                parent[path[-1]] = draw(VALUES)
        elif isinstance(parent, dict):  # an unknown key beside a known one
            parent[draw(KEYS)] = draw(VALUES)
    text = yaml.safe_dump(data, allow_unicode=True)
    encoding = draw(st.sampled_from(["utf-8", "utf-16", "latin-1", "garbage"]))
    if encoding == "garbage":
        return text.encode("utf-8", "surrogatepass")[: draw(st.integers(0, 400))] + draw(st.binary(max_size=20))
    return text.encode(encoding, errors="replace")


@FUZZ
@given(mutated_configs())
def test_a_fuzzed_config_is_loaded_or_refused_naming_the_field(tmp_path: Path, raw: bytes) -> None:
    path = tmp_path / "fuzz.yaml"
    path.write_bytes(raw)
    try:
        config = load_config(path)
    except ConfigError as exc:
        assert exc.problems and all(":" in problem for problem in exc.problems), exc.problems
        return
    assert config.cameras and config.projectors  # accepted: a whole rig


@FUZZ
@given(st.integers(min_value=50, max_value=1200), st.sampled_from(["[", "{a: ", "- "]))
def test_deep_nesting_is_refused_not_a_recursion_error(tmp_path: Path, depth: int, opener: str) -> None:
    path = tmp_path / "deep.yaml"
    path.write_text(opener * depth)
    with pytest.raises(ConfigError):
        load_config(path)


# --- mesh files --------------------------------------------------------------------------------

COORD = st.one_of(
    st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, width=32),
    st.sampled_from([0.0, 1.0, math.nan, math.inf, -math.inf, 1e-30, 3e38, -3e38]),
)


@st.composite
def ply_meshes(draw: st.DrawFn) -> bytes:
    vertices = draw(st.lists(st.tuples(COORD, COORD, COORD), min_size=0, max_size=12))
    if draw(st.booleans()) and vertices:
        vertices = [vertices[0]] * len(vertices)  # every vertex at one point
    n = max(len(vertices), 1)
    faces = draw(st.lists(st.tuples(*[st.integers(-1, n + 1)] * 3), min_size=0, max_size=12))
    head = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    body = b"".join(struct.pack("<3f", *v) for v in vertices)
    body += b"".join(struct.pack("<B3i", 3, *f) for f in faces)
    data = head + body
    if draw(st.booleans()):
        data = data[: draw(st.integers(0, len(data)))]  # truncated
    return data


@FUZZ
@given(
    st.one_of(ply_meshes(), st.binary(max_size=300)),
    st.sampled_from([".ply", ".obj", ".stl"]),
)
def test_a_fuzzed_mesh_file_gives_a_usable_mesh_or_a_clear_refusal(tmp_path: Path, raw: bytes, suffix: str) -> None:
    path = tmp_path / f"fuzz{suffix}"
    path.write_bytes(raw)
    try:
        obj = mesh_file(path, fit_size_mm=150.0)
    except ValueError as exc:
        assert str(path) in str(exc)
        return
    mesh = trimesh.Trimesh(obj.vertices, obj.faces, process=False)
    assert len(mesh.faces) and np.isfinite(mesh.vertices).all()
    assert float(mesh.area_faces.min()) > 0 and max(mesh.extents) == pytest.approx(150.0)


# --- request bodies ----------------------------------------------------------------------------

BODIES = {  # every operation that takes a JSON body, and the model that reads it
    "/v1/scans": ScanRequest,
    "/v1/calibrations": CalibrationRequest,
    "/v1/gallery": GalleryAddRequest,
    "/v1/reconstructions": ReconstructionRequest,
    "/v1/scans/20261125-000000-abcdef/reprocess": ReprocessRequest,
    "/v1/scans/20261125-000000-abcdef/identify": IdentifyRequest,
}
UNREPRESENTABLE = ["NaN", "-Infinity", "1e999", '"\\ud800"', '"a\\udfffb"']  # JSON that cannot echo them


@st.composite
def bodies(draw: st.DrawFn) -> tuple[str, str]:
    """An operation and a body for it: arbitrary JSON, the model's own fields with any values
    (non-finite numbers and lone surrogates among them), or bytes that are not JSON at all."""
    url = draw(st.sampled_from(sorted(BODIES)))
    fields = sorted(BODIES[url].model_fields)
    kind = draw(st.sampled_from(["json", "fields", "bytes"]))
    if kind == "json":
        return url, json.dumps(draw(VALUES), allow_nan=True)
    if kind == "bytes":
        return url, draw(st.binary(max_size=60)).decode("latin-1")
    chosen = draw(st.dictionaries(st.sampled_from(fields), st.one_of(VALUES, st.sampled_from(UNREPRESENTABLE))))
    return url, "{" + ", ".join(f"{json.dumps(k)}: {_raw(v)}" for k, v in chosen.items()) + "}"


def _raw(value: Any) -> str:
    """A JSON value, or a token JSON has no value for (NaN, 1e999, a lone surrogate) as it is."""
    if isinstance(value, str) and value in UNREPRESENTABLE:
        return value
    return json.dumps(value, allow_nan=True)


@pytest.fixture(scope="module")
def idle_client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    service = _service(tmp_path_factory.mktemp("fuzz"), start=False, max_queue=1000)
    with _client(service) as client:
        yield client
    service.store.close()


@FUZZ
@given(bodies())
def test_a_fuzzed_request_body_gets_an_answer_not_a_500(idle_client: TestClient, request_body: tuple[str, str]) -> None:
    url, body = request_body
    answer = idle_client.post(
        url, content=body.encode("utf-8", "surrogatepass"), headers={**AUTH, "Content-Type": "application/json"}
    )
    assert answer.status_code < 500, answer.text
    if answer.status_code == 422:
        detail = answer.json()["detail"]
        assert isinstance(detail, str) or all(item.get("loc") for item in detail)


def _ply(vertices: list[tuple[float, float, float]], faces: list[tuple[int, int, int]]) -> str:
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(vertices)}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {len(faces)}",
        "property list uchar int vertex_indices",
        "end_header",
        *(" ".join(str(c) for c in v) for v in vertices),
        *(f"3 {a} {b} {c}" for a, b, c in faces),
    ]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        (_ply([(1, 1, 1)] * 3, [(0, 1, 2)]), "zero area"),  # every vertex at one point
        (_ply([(0, 0, 0), (1, 1, 1), (2, 2, 2)], [(0, 1, 2)]), "zero area"),  # on a line
        (_ply([(0, 0, 0), (1, 0, 0), (float("nan"), 1, 0)], [(0, 1, 2)]), "not finite"),
        (_ply([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 7)]), "not in the file"),
        (_ply([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])[:-12], "cannot read"),  # truncated
    ],
)
def test_a_mesh_scene_without_usable_triangles_exits_2_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, reason: str
) -> None:
    from rig.cli import main

    mesh = tmp_path / "bad.ply"
    mesh.write_text(text)
    assert main(["eval", "--scene", str(mesh)]) == 2
    err = capsys.readouterr().err
    assert "simulation.scene.path" in err and reason in err and "Traceback" not in err
