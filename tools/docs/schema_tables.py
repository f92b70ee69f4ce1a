"""JSON Schema (as pydantic and FastAPI write it) as Markdown tables: one section per object model,
a row per field with its type, default, bounds and description, models linked to their sections."""

from __future__ import annotations

import json
from typing import Any

BOUNDS = (
    ("minimum", ">= {}"),
    ("exclusiveMinimum", "> {}"),
    ("maximum", "<= {}"),
    ("exclusiveMaximum", "< {}"),
    ("minLength", "at least {} characters"),
    ("maxLength", "at most {} characters"),
    ("minItems", "at least {} item(s)"),
    ("maxItems", "at most {} item(s)"),
    ("pattern", "matches `{}`"),
)


def anchor(name: str) -> str:
    return name.lower().replace("_", "-")


def type_of(schema: dict[str, Any]) -> str:
    """A field's type as a reader says it: string, integer, list of X, Model (linked), a | b."""
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[-1]
        return f"[{name}](#{anchor(name)})"
    if "const" in schema:
        return f"`{json.dumps(schema['const'])}`"
    if "enum" in schema:
        return " | ".join(f"`{json.dumps(v)}`" for v in schema["enum"])
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return " | ".join(dict.fromkeys(type_of(s) for s in schema[key]))
    kind = schema.get("type")
    if kind == "array":
        items = schema.get("prefixItems")
        if items:
            return "[" + ", ".join(type_of(i) for i in items) + "]"
        return f"list of {type_of(schema.get('items', {}))}"
    if kind == "object":
        extra = schema.get("additionalProperties")
        return f"map of {type_of(extra)}" if isinstance(extra, dict) and extra else "object"
    if isinstance(kind, list):
        return " | ".join(kind)
    return str(kind or "any")


def bounds_of(schema: dict[str, Any]) -> str:
    found = [text.format(schema[key]) for key, text in BOUNDS if key in schema]
    for key in ("anyOf", "oneOf"):
        for option in schema.get(key, []):
            found += [text.format(option[k]) for k, text in BOUNDS if k in option]
    return "; ".join(dict.fromkeys(found))


def cell(text: object) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def model_table(name: str, schema: dict[str, Any], level: int = 3) -> list[str]:
    """A model's section: its description, then a row per field."""
    lines = [f"{'#' * level} {name}", ""]
    if schema.get("description"):
        lines += [cell(schema["description"]), ""]
    properties = schema.get("properties", {})
    if not properties:
        return [*lines, f"Type: {type_of(schema)}.", ""]
    required = set(schema.get("required", []))
    lines += ["| field | type | default | bounds | description |", "|---|---|---|---|---|"]
    for field, spec in properties.items():
        default = "required" if field in required else _default(spec.get("default"))
        row = [f"`{field}`", type_of(spec), default, bounds_of(spec), spec.get("description", "")]
        lines.append("| " + " | ".join(cell(c) for c in row) + " |")
    return [*lines, ""]


def schema_sections(root_name: str, schema: dict[str, Any], definitions: dict[str, Any], level: int = 3) -> list[str]:
    """The root model and every model it reaches, in the order a reader meets them."""
    seen: list[str] = []

    def visit(node: Any) -> None:
        if isinstance(node, dict):
            ref = node.get("$ref")
            if ref:
                name = ref.rsplit("/", 1)[-1]
                if name not in seen and name in definitions:
                    seen.append(name)
                    visit(definitions[name])
            for value in node.values():
                visit(value)
        elif isinstance(node, list):
            for value in node:
                visit(value)

    visit({k: v for k, v in schema.items() if k != "$defs"})
    lines = model_table(root_name, schema, level)
    for name in seen:
        lines += model_table(name, definitions[name], level)
    return lines


def _default(value: Any) -> str:
    """A default as the config file would spell it; a section's defaults are its own fields'."""
    if isinstance(value, dict) and value:
        return "its fields' defaults"
    text = json.dumps(value)
    return f"`{text}`" if len(text) <= 60 else f"`{text[:57]}...`"
