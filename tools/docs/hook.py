"""MkDocs hook (mkdocs.yml `hooks:`): the reference pages, written from the code each time the
manual is built, so they cannot drift from it. The pages exist only in the built site."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))  # the manual is built from the checkout it documents

from reference_cli import cli_page  # noqa: E402
from reference_config import config_page, drivers_page  # noqa: E402
from reference_formats import calibration_files_page, manifest_page, patterns_page  # noqa: E402
from reference_rest import rest_page  # noqa: E402

PAGES: dict[str, Callable[[], str]] = {
    "reference/cli.md": cli_page,
    "reference/configuration.md": config_page,
    "reference/rest.md": rest_page,
    "reference/drivers.md": drivers_page,
    "reference/pattern-description.md": patterns_page,
    "reference/manifest.md": manifest_page,
    "reference/calibration-files.md": calibration_files_page,
}


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    for uri, page in PAGES.items():
        files.append(File.generated(config, uri, content=page()))
    return files
