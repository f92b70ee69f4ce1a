"""Codecs by name: `codec_class("gray")`. Importing this package registers the built-in codecs."""

from rig.lazy import face
from rig.patterns import cued_phase as _cued_phase  # noqa: F401 - registers the codec
from rig.patterns import gray as _gray  # noqa: F401 - registers the codec
from rig.patterns import phase as _phase  # noqa: F401 - registers the codec
from rig.patterns import radial as _radial  # noqa: F401 - registers the codec
from rig.patterns import rings as _rings  # noqa: F401 - registers the codec
from rig.patterns.base import Codec, CodecParams
from rig.patterns.correspondence import Correspondence, RingSamples
from rig.patterns.registry import codec_class, codec_names

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "CuedPhaseParams": "cued_phase",
    "EDGE_RAMP_PX": "rings",
    "FrameFiles": "spec",
    "FrameStream": "stream",
    "GrayParams": "gray",
    "LineCodec": "lines",
    "PatternSpec": "spec",
    "PhaseCodec": "phase",
    "PhaseParams": "phase",
    "RadialParams": "radial",
    "RingsParams": "rings",
    "SETUP_PATTERNS": "setup",
    "decode_described": "described",
    "decode_streamed": "stream",
    "decoded_warnings": "described_checks",
    "farthest_corner_px": "circular",
    "sent_levels": "base",
    "setup_pattern": "setup",
    "sharpness": "setup",
    "subset_samples": "saturation",
    "without_pixels": "saturation",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "EDGE_RAMP_PX",
    "SETUP_PATTERNS",
    "Codec",
    "CodecParams",
    "Correspondence",
    "CuedPhaseParams",
    "FrameFiles",
    "FrameStream",
    "GrayParams",
    "LineCodec",
    "PatternSpec",
    "PhaseCodec",
    "PhaseParams",
    "RadialParams",
    "RingSamples",
    "RingsParams",
    "codec_class",
    "codec_names",
    "decode_described",
    "decode_streamed",
    "decoded_warnings",
    "farthest_corner_px",
    "sent_levels",
    "setup_pattern",
    "sharpness",
    "subset_samples",
    "without_pixels",
]
