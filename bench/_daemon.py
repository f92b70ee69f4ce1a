"""The configs the reliability benchmarks start a real daemon with (tests/test_daemon.py's Daemon)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.conftest import small_config_data


def daemon_config(
    folder: Path, data_dir: Path, data: dict[str, Any] | None = None, stall: bool = False, **service: Any
) -> Path:
    """A config file in `folder` keeping its data in `data_dir`: the suite's small bench (quick
    scans) unless `data` is given; `stall`: its first camera stops after 3 frames (a 60 s capture
    timeout); `service`: the service section."""
    data = small_config_data() if data is None else data
    data["output"] = {"data_dir": str(data_dir)}
    data["service"] = service
    if stall:
        data["cameras"][0]["sim"]["faults"] = {"stall_after_frames": 3}
        data.setdefault("scan", {})["capture_timeout_s"] = 60.0
    path = folder / f"daemon-{len(list(folder.glob('daemon-*.yaml')))}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path
