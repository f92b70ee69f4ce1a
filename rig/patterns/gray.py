"""`gray`: binary Gray code with inverse patterns, columns and optionally rows."""

from __future__ import annotations

import numpy as np

from rig.patterns.correspondence import Correspondence, NormalizedFrames, least_counts
from rig.patterns.graycode import bit_count, decode_gray, gray_planes, planes_with_inverses
from rig.patterns.lines import LineCodec, LineParams
from rig.patterns.registry import register
from rig.patterns.spec import GrayCode, PatternSpec, ProjectorSpace
from rig.patterns.stream import DenseBase, FrameStream, GrayBits


class GrayParams(LineParams):
    """Gray code: one bit plane and its inverse per bit, ceil(log2(extent)) bits per direction."""


@register
class GrayCodec(LineCodec):
    name = "gray"
    quantized = True
    Params = GrayParams
    params: GrayParams

    def description(self) -> PatternSpec:
        """This codec's frames as a pattern description (rig.patterns.spec): the one reader of
        others' captures reads slrig's own."""
        return PatternSpec(
            projector=ProjectorSpace(resolution=(self.width, self.height)),
            gray=GrayCode(
                axes=tuple("columns" if axis == "u" else "rows" for axis in self.axes()),
                white_black="first",
                min_contrast=self.params.white_threshold,
                black_threshold=self.params.black_threshold,
            ),
        )

    def _coded_frame_count(self) -> int:
        return sum(2 * bit_count(self.extent(axis)) for axis in self.axes())

    def _coded_lines(self) -> list[tuple[np.ndarray, str]]:
        out: list[tuple[np.ndarray, str]] = []
        for axis in self.axes():
            n = self.extent(axis)
            out += [(line, axis) for line in planes_with_inverses(gray_planes(np.arange(n), bit_count(n)))]
        return out

    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        coords: dict[str, np.ndarray] = {}
        valid = lit.copy()
        counts = {"lit": int(lit.sum())}
        offset = 0
        for axis in self.axes():
            n = self.extent(axis)
            bits = bit_count(n)
            value, strength = decode_gray(frames[offset : offset + 2 * bits], bits)
            offset += 2 * bits
            ok = (strength >= self.params.white_threshold) & (value < n)
            counts[f"weak_bits_{axis}"] = int((lit & ~ok).sum())
            valid &= ok
            coords[axis] = value.astype(np.float32)
        return self.correspondence(coords, valid, white - black, texture, counts)

    def stream(self, full_scale: int) -> FrameStream:
        return GrayStream(self, full_scale)


class GrayStream(FrameStream):
    """The Gray decoder fed frame by frame: each (pattern, inverse) pair is read in integer counts
    when its inverse arrives (GrayBits); the last one leaves only the coordinates to write."""

    codec: GrayCodec

    def __init__(self, codec: GrayCodec, full_scale: int) -> None:
        super().__init__(codec, full_scale)
        # the axes still to read, in order, each with its extent and the reader of its code
        self._pending = [(axis, codec.extent(axis), GrayBits(bit_count(codec.extent(axis)))) for axis in codec.axes()]
        self._min_strength = least_counts(codec.params.white_threshold, full_scale)
        self._base = DenseBase(codec, full_scale)
        self._coords: dict[str, np.ndarray] = {}

    def _consume(self, index: int, frame: np.ndarray) -> None:
        image = self._base.coded_frame(index, frame)
        if image is None:
            return
        axis, extent, reader = self._pending[0]
        if reader.take(image):
            self._coords[axis] = self._base.accept(reader, extent, self._min_strength, f"weak_bits_{axis}")
            self._pending.pop(0)  # its images go with it

    def _finish(self) -> Correspondence:
        return self._base.correspondence(self._coords, self._base.contrast())
