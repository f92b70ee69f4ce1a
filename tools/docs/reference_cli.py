"""The command line's reference, from its argument parsers (rig.cli.arguments)."""

from __future__ import annotations

import argparse

from schema_tables import cell

from rig.cli.arguments import parser


def cli_page() -> str:
    root = parser()
    lines = [
        "# Command line",
        "",
        "Every command and option of `slrig`, written from its argument parsers (`rig/cli/arguments.py`)",
        "when this manual is built. `slrig COMMAND --help` prints the same.",
        "",
    ]
    for path, sub, summary in _commands(root, "slrig"):
        lines += [f"## {path}", ""]
        if summary:
            lines += [cell(summary), ""]
        if sub.description and sub.description != summary:
            lines += [cell(sub.description), ""]
        lines += ["```text", sub.format_usage().strip(), "```", ""]
        rows = [_row(action) for action in sub._actions if _shown(action)]
        if rows:
            lines += ["| argument | default | meaning |", "|---|---|---|", *rows, ""]
    return "\n".join(lines)


def _commands(p: argparse.ArgumentParser, path: str) -> list[tuple[str, argparse.ArgumentParser, str]]:
    """Every command below `p`, depth first, with the help its parent gives it."""
    found = []
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            for name, sub in action.choices.items():
                found.append((f"{path} {name}", sub, helps.get(name, "")))
                found += _commands(sub, f"{path} {name}")
    return found


def _shown(action: argparse.Action) -> bool:
    return not isinstance(action, (argparse._HelpAction, argparse._SubParsersAction))


def _row(action: argparse.Action) -> str:
    name = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.metavar or action.dest}`"
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        name += " (" + ", ".join(f"`{c}`" for c in action.choices) + ")"
    if action.option_strings and action.nargs != 0 and action.metavar is None:
        name += f" {action.dest.upper()}"
    default = "" if action.default in (None, False, argparse.SUPPRESS) else f"`{action.default}`"
    return f"| {cell(name)} | {cell(default)} | {cell(action.help or '')} |"
