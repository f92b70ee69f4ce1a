"""Codecs by name: `codec_class("gray")`. Importing this package registers the built-in codecs."""

from rig.patterns import gray as _gray  # noqa: F401 - registers the codec
from rig.patterns import phase as _phase  # noqa: F401 - registers the codec
from rig.patterns.base import Codec, CodecParams, Correspondence
from rig.patterns.registry import codec_class, codec_names

__all__ = ["Codec", "CodecParams", "Correspondence", "codec_class", "codec_names"]
