"""Reading a rig description: YAML (or data) validated into a RigConfig, with paths resolved."""

from __future__ import annotations

from pathlib import Path

import yaml

from rig.config.rig import RigConfig, validate_rig
from rig.config.scenes import ImageTexture, MeshScene
from rig.errors import ConfigError

REPO_CONFIG_DIR = Path(__file__).resolve().parent.parent.parent / "config"
DEFAULT_CONFIG = REPO_CONFIG_DIR / "sim.yaml"


def config_from_dict(data: object, source: str) -> RigConfig:
    """Validate a config given as data (a stored scan's snapshot, a request) like a file."""
    config = validate_rig(data, source)
    _check_files(config, source)
    return config


def load_config(path: str | Path | None = None) -> RigConfig:
    """Read and validate a rig description; raises ConfigError listing every problem."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    source = str(path)
    if not path.is_file():
        raise ConfigError(source, [f"(file): no such file: {path}"])
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ConfigError(source, [f"(file): not valid YAML: {exc}"]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(source, [f"(file): cannot read: {exc}"]) from None
    except RecursionError:
        raise ConfigError(source, ["(file): nested too deeply to be a rig description"]) from None
    if not isinstance(data, dict):
        raise ConfigError(source, ["(top level): expected a mapping of sections"])
    _resolve_paths(data, path.parent)
    config = validate_rig(data, source)
    _check_files(config, source)
    return config


def _resolve_paths(data: dict, base: Path) -> None:  # type: ignore[type-arg]
    """Paths in the file are relative to the file's folder."""

    def resolve(section: object, key: str) -> None:
        if isinstance(section, dict) and isinstance(section.get(key), str):
            p = Path(section[key]).expanduser()
            section[key] = str(p if p.is_absolute() else (base / p).resolve())

    simulation = data.get("simulation")
    resolve(simulation.get("scene") if isinstance(simulation, dict) else None, "path")
    resolve(simulation.get("texture") if isinstance(simulation, dict) else None, "path")
    resolve(data.get("calibration"), "file")
    for camera in data.get("cameras") or []:
        resolve(camera.get("replay") if isinstance(camera, dict) else None, "source")


def _check_files(config: RigConfig, source: str) -> None:
    scene = config.simulation.scene if config.simulation else None
    if isinstance(scene, MeshScene) and not scene.path.is_file():
        raise ConfigError(source, [f"simulation.scene.path: mesh file not found: {scene.path}"])
    texture = config.simulation.texture if config.simulation else None
    if isinstance(texture, ImageTexture) and not texture.path.is_file():
        raise ConfigError(source, [f"simulation.texture.path: image file not found: {texture.path}"])
    file = config.calibration.file
    if file is not None and not (
        file.is_file() or (file / "calibration.json").is_file() or (file / "response.json").is_file()
    ):
        raise ConfigError(source, [f"calibration.file: no calibration.json or response.json at {file}"])
