"""Config validation: every problem listed, each naming its field."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.config import load_config
from rig.config.loading import REPO_CONFIG_DIR
from rig.errors import ConfigError
from tests.conftest import default_config_data, write_config


def test_default_config_is_the_simulated_bench() -> None:
    config = load_config()
    assert config.projectors[0].resolution == (1024, 768)
    assert config.cameras[0].resolution == (1280, 1024)
    assert config.simulation is not None and config.simulation.scene.kind == "sphere_on_plane"
    baseline = abs(config.projectors[0].geometry.pose.position_mm[0] - config.cameras[0].geometry.pose.position_mm[0])
    assert 150 <= baseline <= 250


def _problems(tmp_path: Path, data: dict) -> list[str]:  # type: ignore[type-arg]
    with pytest.raises(ConfigError) as info:
        load_config(write_config(tmp_path, data))
    return info.value.problems


@pytest.mark.parametrize("name", sorted(p.name for p in REPO_CONFIG_DIR.glob("*.yaml")))
def test_every_shipped_config_loads_and_its_mesh_is_there(name: str) -> None:
    config = load_config(REPO_CONFIG_DIR / name)
    scene = config.simulation.scene if config.simulation is not None else None
    if scene is not None and scene.kind == "mesh":
        assert scene.path.is_file()


def test_every_error_is_listed_with_its_field(tmp_path: Path) -> None:
    data = default_config_data()
    data["cameras"][0]["resolution"] = [1280, 5]
    data["cameras"][0]["exposure_us"] = -3
    data["projectors"][0]["colour"] = "blue"
    problems = _problems(tmp_path, data)
    assert any(p.startswith("cameras[0].resolution[1]:") and "16" in p for p in problems)
    assert any(p.startswith("cameras[0].exposure_us:") for p in problems)
    assert any(p.startswith("projectors[0].colour:") and "unknown field" in p for p in problems)
    assert len(problems) == 3


def test_scene_errors_name_the_scene_field(tmp_path: Path) -> None:
    data = default_config_data()
    data["simulation"]["scene"] = {"kind": "sphere", "radius_mm": 0}
    assert any(p.startswith("simulation.scene.radius_mm:") for p in _problems(tmp_path, data))
    data["simulation"]["scene"] = {"kind": "teapot"}
    assert any(p.startswith("simulation.scene:") and "teapot" in p for p in _problems(tmp_path, data))


def test_unknown_codec_in_config(tmp_path: Path) -> None:
    data = default_config_data()
    data["scan"]["codec"] = "moire"
    (problem,) = _problems(tmp_path, data)
    assert problem.startswith("scan.codec:") and "gray" in problem


def test_missing_mesh_file_is_a_config_error(tmp_path: Path) -> None:
    data = default_config_data()
    data["simulation"]["scene"] = {"kind": "mesh", "path": "no/such/bunny.ply"}
    (problem,) = _problems(tmp_path, data)
    assert problem.startswith("simulation.scene.path:") and "bunny.ply" in problem


def test_duplicate_device_names(tmp_path: Path) -> None:
    data = default_config_data()
    data["cameras"][0]["name"] = "projector0"
    assert any("unique" in p and "projector0" in p for p in _problems(tmp_path, data))


def test_look_at_must_differ_from_position(tmp_path: Path) -> None:
    data = default_config_data()
    data["cameras"][0]["geometry"]["pose"]["look_at_mm"] = data["cameras"][0]["geometry"]["pose"]["position_mm"]
    assert any(p.startswith("cameras[0].geometry.pose:") for p in _problems(tmp_path, data))


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_config(tmp_path / "absent.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("cameras: [\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(bad)
    bad.write_text("- just a list\n")
    with pytest.raises(ConfigError, match="mapping"):
        load_config(bad)


def test_relative_mesh_path_is_relative_to_the_config(tmp_path: Path) -> None:
    import trimesh

    (tmp_path / "meshes").mkdir()
    trimesh.creation.box(extents=(10, 10, 10)).export(tmp_path / "meshes" / "cube.stl")
    data = default_config_data()
    data["simulation"]["scene"] = {"kind": "mesh", "path": "meshes/cube.stl"}
    config = load_config(write_config(tmp_path, data))
    assert config.simulation is not None
    assert Path(str(config.simulation.scene.path)) == (tmp_path / "meshes" / "cube.stl").resolve()  # type: ignore[union-attr]


def test_unknown_keys_of_any_shape_are_named(tmp_path: Path) -> None:
    """An unknown key is named whether or not it is identifier-shaped (my-key, a key with a space)."""
    data = default_config_data()
    data["my-key"] = 1
    data["scan"]["capture-timeout-s"] = 3
    data["cameras"][0]["exposure ms"] = 5
    with pytest.raises(ConfigError) as caught:
        load_config(write_config(tmp_path, data))
    assert "my-key: unknown field (slrig's keys use '_', not '-')" in caught.value.problems
    assert "scan.capture-timeout-s: unknown field (slrig's keys use '_', not '-')" in caught.value.problems
    assert "cameras[0].exposure ms: unknown field" in caught.value.problems
