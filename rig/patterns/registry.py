"""Codecs by name."""

from __future__ import annotations

from rig.errors import UnknownCodecError
from rig.patterns.base import Codec

_CODECS: dict[str, type[Codec]] = {}


def register(cls: type[Codec]) -> type[Codec]:
    _CODECS[cls.name] = cls
    return cls


def codec_names() -> list[str]:
    return sorted(_CODECS)


def codec_class(name: str) -> type[Codec]:
    try:
        return _CODECS[name]
    except KeyError:
        raise UnknownCodecError(f"unknown codec {name!r}; known codecs: {', '.join(codec_names())}") from None
