"""The codec contract: an encoder that makes pattern images and a decoder that turns captured
frames into a Correspondence. Triangulation depends only on the Correspondence."""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Iterator
from typing import Annotated, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from rig.errors import DecodeError
from rig.patterns.correspondence import (
    Correspondence,
    NormalizedFrames,
)
from rig.patterns.deblur import Deblur
from rig.patterns.saturation import saturated_in, without_saturated
from rig.patterns.spec import PatternSpec
from rig.patterns.spill import without_outshone
from rig.patterns.stream import BufferedStream, FrameStream

PixelCoord = Annotated[float, Field(ge=-1e5, le=1e5)]  # a position in a projector image, pixels


def even_period(value: int) -> int:
    """Validator for fringe periods unwrapped by a half-period Gray code."""
    if value % 2:
        raise ValueError(f"must be even (the unwrapping code works in half periods), got {value}")
    return value


class CodecParams(BaseModel):
    """Parameters every codec has. Thresholds are fractions of the camera's full scale."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    black_threshold: float = Field(
        0.03,
        ge=0.0,
        le=1.0,
        description="minimum (white - black) for a pixel to count as lit: masks shadows and background",
    )


def sent_levels(pattern: np.ndarray, mask: np.ndarray | None, lut: np.ndarray | None) -> np.ndarray:
    """The levels to send for a pattern's light (uint8): dimmed by an intensity `mask` (the share of
    each pixel's light, rig.pipeline.projection_mask), through the projector's inverse response `lut`."""
    if mask is not None:
        pattern = np.rint(pattern * mask).astype(np.uint8)
    return pattern if lut is None else lut[pattern]


class Codec(abc.ABC):
    """Encoder and decoder for one pattern family.

    Frame order is the pattern order; a codec starts with a fully lit and a dark frame, which give
    the texture and the lit mask (one that shows none, rig.patterns.cued_phase, overrides
    `iter_patterns`, `frame_count`, `_decoded` and `references`). Subclasses implement
    `_coded_iter` and `_decode`.
    """

    name: ClassVar[str]
    # Whole projector pixels, not a continuous phase: its error is quantisation, which the decode
    # quality does not predict (merging then ranks points by their measured local noise).
    quantized: ClassVar[bool] = False
    Params: ClassVar[type[CodecParams]] = CodecParams
    # leave out the pixels a far brighter neighbour's blur drowns (rig.patterns.spill)
    drops_outshone: bool = False
    deblur_px: float = 0.0  # the camera's blur, undone before decoding (rig.patterns.deblur); 0: as captured
    # (H, W) float32 in (0, 1], the share of each projector pixel's light that every pattern sends
    # (adaptive projection: rig.pipeline.projection_mask); None sends all of it
    intensity_mask: np.ndarray | None = None

    def __init__(
        self, projector_size: tuple[int, int], params: CodecParams | None = None, output_lut: np.ndarray | None = None
    ) -> None:
        """`output_lut` (256 uint8) maps the light a pattern means to the level to send: the
        inverse of the projector's calibrated response (rig.calibrate.response)."""
        self.width, self.height = projector_size
        self.params = params if params is not None else self.Params()
        self.output_lut = output_lut
        if not isinstance(self.params, self.Params):
            raise TypeError(f"{self.name} codec takes {self.Params.__name__}, got {type(self.params).__name__}")

    def patterns(self) -> list[np.ndarray]:
        """All pattern images (uint8, projector resolution) in projection order."""
        return list(self.iter_patterns())

    def iter_patterns(self) -> Iterator[np.ndarray]:
        """The pattern images of `patterns` one at a time, each made when it is asked for (line
        codecs from 1-D profiles, circular ones from polar images held between them: their
        `_coded_iter`): a capture that shows them one by one then holds the one it shows, not the
        sequence (17 MB of Gray code on the default bench, 75 MB with its temporaries for rings)."""
        white = np.full((self.height, self.width), 255, dtype=np.uint8)
        yield white if self.intensity_mask is None else self._sent(white)  # full white is full light
        yield np.zeros_like(white)
        for pattern in self._coded_iter():
            yield self._sent(pattern)

    def _sent(self, pattern: np.ndarray) -> np.ndarray:
        return sent_levels(pattern, self.intensity_mask, self.output_lut)

    @property
    def frame_count(self) -> int:
        """Patterns per scan, without making them."""
        return 2 + self._coded_frame_count()

    def coded_axes(self) -> str:
        """The projector coordinates a decode gives at each pixel it decodes: "u", "v" or "uv"; ""
        for a sparse codec (ring samples)."""
        return ""

    @property
    def needs_linear_light(self) -> bool:
        """Whether a projector whose light is not linear in the level (an uncorrected gamma) makes
        this codec misread it, not just read it less well: it then needs a DLP's patterns or a
        calibrated response (`slrig calibrate response`)."""
        return False

    def description(self) -> PatternSpec | None:
        """This codec's frames as a pattern description (rig.patterns.spec), so that the reader of
        others' captures reads slrig's own; None where a description cannot say what it shows."""
        return None

    def decode(self, frames: list[np.ndarray], full_scale: int) -> Correspondence:
        """Decode captured frames (one per pattern, same order) taken at `full_scale` counts."""
        expected = self.frame_count
        if len(frames) != expected:
            raise DecodeError(f"{self.name}: expected {expected} frames, got {len(frames)}")
        shapes = {f.shape[:2] for f in frames}
        if len(shapes) != 1:
            raise DecodeError(f"{self.name}: frames differ in size: {sorted(shapes)}")
        if self.deblur_px > 0:
            restore = Deblur(self.deblur_px, full_scale).restored
            frames = [restore(f) for f in frames]
        corr = self._decoded(frames, full_scale)
        saturated = saturated_in(frames, full_scale)
        if saturated is not None:
            corr = without_saturated(corr, saturated)
        if self.drops_outshone:
            corr = without_outshone(corr, *self.references(frames, corr))
        return dataclasses.replace(corr, full_scale=full_scale)

    def _decoded(self, frames: list[np.ndarray], full_scale: int) -> Correspondence:
        """The frames read by `_decode`, after the white and dark frames that give the lit mask."""
        normalized = NormalizedFrames(frames, full_scale)
        white, black = normalized[0], normalized[1]
        lit = (white - black) >= self.params.black_threshold
        return self._decode(NormalizedFrames(frames[2:], full_scale), white, black, lit, frames[0])

    def references(self, frames: list[np.ndarray], corr: Correspondence) -> tuple[np.ndarray, np.ndarray]:
        """The white and the dark frame of a capture (for the spill screen, rig.patterns.spill):
        its first two frames, for every codec that shows them."""
        return frames[0], frames[1]

    @abc.abstractmethod
    def _coded_iter(self) -> Iterator[np.ndarray]:
        """The coded patterns (after the white and dark frames) one at a time, each made as its turn
        comes."""

    @abc.abstractmethod
    def _coded_frame_count(self) -> int: ...

    def stream(self, full_scale: int) -> FrameStream:
        """A decoder fed the frames one at a time as they are captured (rig.patterns.stream); it
        gives what `decode` gives for the same frames. Codecs that can do each frame's work as it
        arrives override this; the default keeps the frames and decodes them at the end."""
        return BufferedStream(self, full_scale)

    @abc.abstractmethod
    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        """`frames` are the coded frames as float32 in [0, 1]."""
