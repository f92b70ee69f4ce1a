"""The manual: the site builds with no broken link or anchor (`mkdocs build --strict`), and every
command of the tutorials that run on the simulated bench works as written, in order, in an empty
folder (a ```bash block runs; a ```shell block is shown only: installs and real hardware)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

TUTORIALS = REPO / "docs" / "tutorials"
RUNS = "<!-- tutorial: the bash blocks of this page run in CI"
BLOCK = re.compile(r"^```bash\n(.*?)^```", re.MULTILINE | re.DOTALL)


def _runnable() -> list[Path]:
    return sorted(p for p in TUTORIALS.glob("*.md") if RUNS in p.read_text())


def test_the_site_builds_strictly(tmp_path: Path) -> None:
    pytest.importorskip("mkdocs", reason="MkDocs is not installed (pip install -e '.[docs]')")
    pytest.importorskip("material", reason="the Material theme is not installed (pip install -e '.[docs]')")
    built = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert built.returncode == 0, built.stderr[-4000:]
    for page in ("reference/cli", "reference/configuration", "reference/rest", "tutorials/first-scan"):
        assert (tmp_path / "site" / page / "index.html").is_file(), page
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "--save-frames" in cli and "slrig store migrate" in cli  # written from the parsers themselves


def test_every_simulated_tutorial_has_commands() -> None:
    pages = _runnable()
    assert len(pages) >= 5
    for page in pages:
        assert BLOCK.findall(page.read_text()), f"{page.name}: marked to run, but has no bash block"


@pytest.mark.parametrize("page", _runnable(), ids=lambda p: p.stem)
def test_the_tutorial_runs_as_written(page: Path, tmp_path: Path) -> None:
    (tmp_path / "config").symlink_to(REPO / "config")  # as in a clone: config/sim-face.yaml and the rest
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    for number, block in enumerate(BLOCK.findall(page.read_text()), 1):
        ran = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", block],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=600,
            env=env,
        )
        assert ran.returncode == 0, f"{page.name}, block {number}:\n{block}\n{ran.stdout[-2000:]}\n{ran.stderr[-3000:]}"


def test_the_manifest_reference_lists_what_a_scan_writes(tmp_path: Path) -> None:
    from rig.assembly import open_rig
    from rig.config import load_config
    from rig.service.tasks import scan_to_directory
    from rig.store.manifest_fields import MANIFEST_FIELDS
    from tests.conftest import small_config_data, write_config

    config = load_config(write_config(tmp_path, small_config_data()))
    seen: set[str] = set()
    with open_rig(config) as rig:
        for number, codec in enumerate(("gray", "rings")):  # a ring scan adds its surface
            path, _ = scan_to_directory(rig, tmp_path / codec, f"20261127-120000-00000{number}", codec)
            seen |= set(json.loads((path / "manifest.json").read_text()))
    assert seen <= set(MANIFEST_FIELDS), seen - set(MANIFEST_FIELDS)  # nothing written goes undocumented
    writer = (REPO / "rig" / "store" / "scandir.py").read_text()
    assert all(f'"{key}":' in writer for key in MANIFEST_FIELDS)  # nothing documented that it cannot write
