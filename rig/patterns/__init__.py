"""Codecs by name: `codec_class("gray")`. Importing this package registers the built-in codecs."""

from rig.patterns import cued_phase as _cued_phase  # noqa: F401 - registers the codec
from rig.patterns import gray as _gray  # noqa: F401 - registers the codec
from rig.patterns import phase as _phase  # noqa: F401 - registers the codec
from rig.patterns import radial as _radial  # noqa: F401 - registers the codec
from rig.patterns import rings as _rings  # noqa: F401 - registers the codec
from rig.patterns.base import Codec, CodecParams
from rig.patterns.correspondence import Correspondence, RingSamples
from rig.patterns.registry import codec_class, codec_names

__all__ = ["Codec", "CodecParams", "Correspondence", "RingSamples", "codec_class", "codec_names"]
