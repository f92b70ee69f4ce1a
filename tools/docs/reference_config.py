"""The configuration's reference, from its pydantic models' JSON schema, and the driver table."""

from __future__ import annotations

from schema_tables import cell, schema_sections

from rig.config import RigConfig
from rig.config.drivers import DRIVERS


def config_page() -> str:
    schema = RigConfig.model_json_schema()
    lines = [
        "# Configuration",
        "",
        "Every section and field of a rig description (YAML), written from the pydantic models in",
        "`rig/config/` when this manual is built: each field's type, default, bounds and meaning. Lengths",
        "are in millimetres (`_mm`), times in seconds (`_s`) or microseconds (`_us`), angles in degrees",
        "(`_deg`) unless a field says otherwise. A field that is not listed is refused, naming it.",
        "",
    ]
    lines += schema_sections("RigConfig", schema, schema.get("$defs", {}), level=2)
    return "\n".join(lines)


def drivers_page() -> str:
    lines = [
        "# Drivers",
        "",
        "Every `driver:` (and power `protocol:`) a config may name, from the table in",
        "`rig/config/drivers.py` that the config checks and the assembly build from.",
        "",
        "| kind | driver | config sections | can | simulated | what it is |",
        "|---|---|---|---|---|---|",
    ]
    for entry in DRIVERS:
        caps = [name.replace("_", " ") for name, on in vars(entry.capabilities).items() if on]
        sections = ", ".join(f"`{s}`" for s in entry.sections) or "none"
        row = [
            entry.kind.value,
            f"`{entry.name}`",
            sections,
            ", ".join(caps) or "",
            "yes" if entry.simulated else "",
            entry.summary,
        ]
        lines.append("| " + " | ".join(cell(c) for c in row) + " |")
    for entry in DRIVERS:
        for section, model in entry.sections.items():
            schema = model.model_json_schema()
            lines += ["", *schema_sections(f"{entry.name}: `{section}`", schema, schema.get("$defs", {}), level=2)]
    return "\n".join(lines)
