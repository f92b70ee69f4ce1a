"""The REST API's reference, from the OpenAPI document the daemon itself serves (/openapi.json)."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import yaml
from schema_tables import anchor, cell, model_table

from rig.api.app import create_app
from rig.api.security import ApiSettings
from rig.config import config_from_dict
from rig.config.loading import DEFAULT_CONFIG
from rig.service.job_service import JobService

METHODS = ("get", "post", "put", "delete")


def openapi_document() -> dict[str, Any]:
    """The OpenAPI document of a daemon on the simulated bench (its store in a throw-away folder)."""
    with tempfile.TemporaryDirectory() as folder:
        data = yaml.safe_load(DEFAULT_CONFIG.read_text())
        data["output"] = {"data_dir": str(Path(folder) / "data")}
        service = JobService(config_from_dict(data, "the manual's simulated bench"))
        try:
            return create_app(service, ApiSettings(api_key="k" * 32)).openapi()
        finally:
            service.store.close()


def rest_page() -> str:
    document = openapi_document()
    lines = [
        "# REST API",
        "",
        "Every endpoint of `slrig serve`, written from the OpenAPI document the daemon serves",
        "(`/openapi.json`; `/docs` draws it) when this manual is built. Bodies are JSON; a field that is",
        "not listed is refused (422) naming it. The table gives each endpoint's success answers; any may",
        "also answer an error (401 or 403 for the key, 404, 409, 413, 422, 429, 503, 507), whose body's",
        "`detail` says why. [The service](../service.md) says how keys, limits and errors work, with examples.",
        "",
    ]
    by_tag: dict[str, list[str]] = {}
    for path, operations in document["paths"].items():
        for method in METHODS:
            if method in operations:
                op = operations[method]
                by_tag.setdefault((op.get("tags") or ["other"])[0], []).append(_endpoint(method, path, op))
    for tag, rows in by_tag.items():
        lines += [f"## {tag}", "", "| endpoint | body | success | what it does |", "|---|---|---|---|", *rows, ""]
    lines += ["## Bodies", ""]
    for name, schema in document.get("components", {}).get("schemas", {}).items():
        lines += model_table(name, schema, level=3)
    return "\n".join(lines)


def _endpoint(method: str, path: str, op: dict[str, Any]) -> str:
    body = op.get("requestBody", {}).get("content", {})
    if "application/json" in body:
        ref = body["application/json"].get("schema", {}).get("$ref", "")
        shown = f"[{ref.rsplit('/', 1)[-1]}](#{anchor(ref.rsplit('/', 1)[-1])})" if ref else "JSON"
    elif body:
        shown = next(iter(body))
    else:
        shown = ""
    answers = ", ".join(code for code in op.get("responses", {}) if code.startswith(("2", "3")))
    what = op.get("description") or op.get("summary") or ""
    return f"| `{method.upper()} {path}` | {shown} | {answers} | {cell(what.strip().split(chr(10) + chr(10))[0])} |"
