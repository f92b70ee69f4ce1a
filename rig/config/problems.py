"""Pydantic's validation errors as one line per problem, each starting with the field it is about."""

from __future__ import annotations

from pydantic import ValidationError

from rig.config.scenes import SCENE_SHAPES


def _location(loc: tuple[int | str, ...]) -> str:
    out = ""
    for i, item in enumerate(loc):
        if isinstance(item, int):
            out += f"[{item}]"
        elif i > 0 and loc[i - 1] == "scene" and item in SCENE_SHAPES:
            continue  # the discriminator's tag adds nothing for the reader
        elif not str(item).isidentifier():
            continue  # a union member's tag, e.g. 'tuple[constrained-float, ...]'
        else:
            out += ("." if out else "") + str(item)
    return out


def validation_problems(exc: ValidationError) -> list[str]:
    """One line per problem, each starting with the field it is about. Of the errors a union
    field gets (one per member it failed), the most specific is kept."""
    by_field: dict[str, tuple[int, str]] = {}
    for error in exc.errors():
        message = error["msg"].removeprefix("Value error, ")
        where = _location(error["loc"])
        if error["type"] == "extra_forbidden":  # the unknown key itself, whatever its shape
            key = str(error["loc"][-1])
            hint = " (slrig's keys use '_', not '-')" if "-" in key else ""
            where = _location(error["loc"][:-1])
            by_field[f"{where}/{key}"] = (0, f"{where + '.' if where else ''}{key}: unknown field{hint}")
            continue
        if not where:  # a check across fields: its message names the field
            by_field.setdefault(message, (0, message))
            continue
        loc = error["loc"]
        tags = [i for i, item in enumerate(loc) if isinstance(item, str) and not item.isidentifier()]
        key = _location(loc[: tags[0]]) if tags else where  # the union field, whatever member failed
        if key not in by_field or len(loc) > by_field[key][0]:
            by_field[key] = (len(loc), f"{where}: {message}")
    return [line for _, line in by_field.values()]
