"""The architecture of docs/architecture.md, checked: the layer contracts hold, runtime code never
loads the simulator, the driver table and the config agree, and modules and functions stay small
enough to read in one sitting."""

from __future__ import annotations

import ast
import json
import os
import re
import shutil
import subprocess
import sys
import typing
from pathlib import Path

import pytest
import yaml

from rig.assembly.build import factory_of
from rig.config import DRIVERS, CameraConfig, DeviceKind, PowerConfig, ProjectorConfig, drivers_of, named
from rig.config.loading import REPO_CONFIG_DIR
from tests.conftest import REPO

MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 60
# (path, function) -> why it may be longer; none today
LONG_FUNCTIONS: dict[tuple[str, str], str] = {}
CODE = ("rig", "drivers", "bench", "tests", "docs")


def test_the_import_contracts_hold() -> None:
    linter = shutil.which("lint-imports") or str(Path(sys.executable).parent / "lint-imports")
    done = subprocess.run([linter], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "5 kept, 0 broken" in done.stdout


def test_every_module_of_rig_has_a_floor_and_runtime_code_no_fake(tmp_path: Path) -> None:
    """The contracts catch what they are for: a top-level module left off the layers, and a driver
    that imports a protocol fake (lint-imports on a copy of the code with each added)."""
    linter = shutil.which("lint-imports") or str(Path(sys.executable).parent / "lint-imports")
    for name in ("rig", "drivers", "tests"):
        shutil.copytree(REPO / name, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__", "*.nbc", "*.nbi"))
    shutil.copy(REPO / "pyproject.toml", tmp_path)
    (tmp_path / "rig" / "stray.py").write_text("X = 1\n")
    (tmp_path / "drivers" / "v4l2_controls.py").write_text(
        (REPO / "drivers" / "v4l2_controls.py").read_text() + "\nimport drivers.fakes.v4l2  # noqa: E402\n"
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run([linter, "--no-cache"], cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode != 0
    assert "every module of \nrig has a floor BROKEN" in done.stdout or "rig has a floor BROKEN" in done.stdout
    assert "(drivers.fakes, drivers.testing) BROKEN" in done.stdout


_PROBE = """
import json, sys
from rig.config import load_config
import rig.cli, rig.cli.serving, rig.daemon.server, rig.service.job_service, rig.assembly.power
from rig.assembly import open_rig
with open_rig(load_config(sys.argv[1])) as the_rig:
    kinds = [type(d).__name__ for d in (*the_rig.projectors, *the_rig.cameras)]
heavy = sorted(m for m in sys.modules if m.split(".")[0] in ("trimesh", "embreex") or m.startswith("drivers.sim"))
print(json.dumps({"devices": kinds, "heavy": heavy}))
"""


def test_a_real_rig_and_the_daemon_never_load_the_simulator(tmp_path: Path) -> None:
    """The daemon's modules, and a rig of real drivers opened and closed (HDMI worker offscreen,
    OAK worker on its fake backend), load neither trimesh, Embree nor drivers.sim."""
    data = yaml.safe_load((REPO_CONFIG_DIR / "bench-hdmi-oak.yaml").read_text())
    projector = data["projectors"][0]
    projector.update(hdmi={"video_driver": "offscreen"})
    del projector["power"]
    data["cameras"][0]["oak"] = {"backend": "fake"}
    path = tmp_path / "real.yaml"
    path.write_text(yaml.safe_dump(data))
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, str(path)], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["devices"] == ["HdmiProjector", "OakCamera"]
    assert found["heavy"] == []


def test_a_simulated_rig_loads_the_simulator_through_the_assembly() -> None:
    """The counterpart of the test above, so that it cannot pass by loading nothing at all."""
    probe = _PROBE.replace("sys.argv[1]", repr(str(REPO_CONFIG_DIR / "sim.yaml")))
    done = subprocess.run([sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert "trimesh" in found["heavy"] and "drivers.sim.bench" in found["heavy"]


@pytest.mark.parametrize("entry", DRIVERS, ids=lambda e: f"{e.kind}:{e.name}")
def test_every_table_entry_resolves_and_its_sections_are_config_fields(entry: typing.Any) -> None:
    assert callable(factory_of(entry))
    model = {DeviceKind.PROJECTOR: ProjectorConfig, DeviceKind.CAMERA: CameraConfig, DeviceKind.POWER: PowerConfig}
    fields = model[entry.kind].model_fields
    for section, options in entry.sections.items():
        if entry.kind is DeviceKind.POWER:  # a power driver's options are the projector's power section
            assert issubclass(PowerConfig, options)
            continue
        assert section in fields, f"{entry.kind} config has no {section!r} section for the {entry.name} driver"
        annotation = fields[section].annotation
        assert options in (annotation, *typing.get_args(annotation)), f"{section}: not a {options.__name__}"


@pytest.mark.parametrize("entry", [e for e in DRIVERS if e.needs is not None], ids=lambda e: f"{e.kind}:{e.name}")
def test_every_machine_check_the_table_names_resolves(entry: typing.Any) -> None:
    assert callable(named(entry.needs))


def test_the_configs_driver_lists_are_the_tables() -> None:
    for kind, field in ((DeviceKind.PROJECTOR, "driver"), (DeviceKind.CAMERA, "driver")):
        model = ProjectorConfig if kind is DeviceKind.PROJECTOR else CameraConfig
        assert set(typing.get_args(model.model_fields[field].annotation)) == set(drivers_of(kind))
    assert set(typing.get_args(PowerConfig.model_fields["protocol"].annotation)) == set(drivers_of(DeviceKind.POWER))


def _sources() -> list[Path]:
    return [path for folder in CODE for path in sorted((REPO / folder).rglob("*.py")) if ".venv" not in path.parts]


def test_modules_and_functions_are_small_enough_to_read_in_one_sitting() -> None:
    long_modules, long_functions = [], []
    for path in _sources():
        text = path.read_text()
        name = str(path.relative_to(REPO))
        if len(text.splitlines()) > MAX_MODULE_LINES:
            long_modules.append(f"{name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES and (name, node.name) not in LONG_FUNCTIONS:
                    long_functions.append(f"{name}:{node.lineno} {node.name}: {length} lines")
    assert not long_modules, f"modules over {MAX_MODULE_LINES} lines: {long_modules}"
    assert not long_functions, f"functions over {MAX_FUNCTION_LINES} lines: {long_functions}"


def test_no_module_imports_itself_back_through_others() -> None:
    """No circle between modules, counting every import: at call time, and under TYPE_CHECKING
    (grimp reads them all). A Protocol says what one module needs of another's class instead."""
    import grimp

    graph = grimp.build_graph("rig", "drivers", cache_dir=None)
    circles = []
    for module in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(module):
            if module < imported and graph.find_shortest_chain(imported=module, importer=imported):
                circles.append(
                    f"{module} <-> {imported}: {graph.find_shortest_chain(imported=module, importer=imported)}"
                )
    assert circles == []


def _packages() -> list[str]:
    return sorted(p.parent.name for p in (REPO / "rig").glob("*/__init__.py"))


def test_packages_are_imported_through_their_faces() -> None:
    """Between rig's packages, imports name the package (its face, `__init__.py`), never one of its
    modules: a package's modules can move and split without its users changing (decision 0033)."""
    packages, reaching = set(_packages()), []
    for path in sorted((REPO / "rig").rglob("*.py")):
        parts = path.relative_to(REPO / "rig").parts
        own = parts[0] if len(parts) > 1 else None
        for node in ast.walk(ast.parse(path.read_text())):
            names = [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
            names += [a.name for a in node.names] if isinstance(node, ast.Import) else []
            for name in names:
                dotted = name.split(".")
                if dotted[0] == "rig" and len(dotted) > 2 and dotted[1] in packages and dotted[1] != own:
                    reaching.append(f"{path.relative_to(REPO)}:{node.lineno} {name}")
    assert reaching == [], f"imports past a package's face: {reaching}"


@pytest.mark.parametrize("package", _packages())
def test_every_name_a_face_offers_is_there(package: str) -> None:
    import importlib

    face = importlib.import_module(f"rig.{package}")
    for name in getattr(face, "__all__", []):
        assert getattr(face, name, None) is not None, f"rig.{package} offers {name} but has none"


def _named_in(page: str) -> tuple[set[str], set[str]]:
    """The dotted names (rig.x.y, drivers.x.y, Codec.x) and the paths (rig/..., tests/...) a page
    puts in backticks."""
    quoted = re.findall(r"`([^`\s]+)`", page)
    dotted = {q.rstrip("()") for q in quoted if re.fullmatch(r"(rig|drivers)(\.\w+)+(\(\))?|Codec\.\w+", q)}
    paths = {q for q in quoted if re.fullmatch(r"(rig|drivers|tests|bench|docs|config)/[\w/.-]+", q)}
    return dotted, paths


def _resolves(name: str) -> bool:
    import importlib

    parts = name.split(".")
    if parts[0] == "Codec":
        parts = ["rig", "patterns", "base", *parts]
    for cut in range(len(parts), 0, -1):
        try:
            target = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attribute in parts[cut:]:
                target = getattr(target, attribute)
        except AttributeError:
            return False
        return True
    return False


def test_every_module_class_and_function_the_architecture_page_names_exists() -> None:
    """docs/architecture.md stays true: what its map and recipes name in backticks is in the code
    (the worked example's GigE camera aside, which is the example)."""
    dotted, paths = _named_in((REPO / "docs" / "architecture.md").read_text())
    assert len(dotted) > 50 and len(paths) > 10
    missing = sorted(n for n in dotted if not _resolves(n))
    assert missing == []
    absent = sorted(p for p in paths if "gige" not in p and not (REPO / p.rstrip("/")).exists())
    assert absent == []
