"""Decoding while capturing: a codec's decoder fed one frame at a time, in pattern order, as the
camera delivers them, so that the work of each frame is done while the next is projected and only a
final step remains after the last one.

`Codec.decode(frames)` (the batch decoder) stays the reference: a stream gives the same
Correspondence for the same frames (bit for bit where a codec's stream works in integer counts,
within float rounding where it sums in another order; tests hold each codec's two together).
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, Protocol

import numpy as np

from rig.errors import DecodeError
from rig.lazy import lazy_module
from rig.patterns.correspondence import Correspondence, luminance
from rig.patterns.deblur import Deblur
from rig.patterns.saturation import SaturationMask
from rig.patterns.spill import SpillScreen
from rig.workers import in_row_strips

kernels = lazy_module("rig.kernels.dense")  # numba compiles on first use: not for --help


class Codec(Protocol):
    """What a stream needs of its codec (rig.patterns.base.Codec is one): its stream does not
    import the codecs' module, which makes streams."""

    name: str
    params: Any
    frame_count: int
    drops_outshone: bool
    deblur_px: float

    def decode(self, frames: list[np.ndarray], full_scale: int) -> Correspondence: ...

    def stream(self, full_scale: int) -> FrameStream: ...


class FrameStream(abc.ABC):
    """One (projector, camera) pair's frames decoded as they arrive: `add` each frame in pattern
    order, then `finish` for the Correspondence. Raises DecodeError for a frame too many, too few,
    or of another size or sample type than the first."""

    def __init__(self, codec: Codec, full_scale: int) -> None:
        self.codec = codec
        self.full_scale = full_scale
        self.added = 0
        self.shape: tuple[int, int] | None = None
        self.dtype: np.dtype | None = None
        self.saturation = SaturationMask(full_scale)
        self.spill = SpillScreen() if codec.drops_outshone else None
        self.deblur = Deblur(codec.deblur_px, full_scale) if codec.deblur_px > 0 else None

    def add(self, frame: np.ndarray) -> None:
        expected = self.codec.frame_count
        if self.added >= expected:
            raise DecodeError(f"{self.codec.name}: expected {expected} frames, got more")
        size = (int(frame.shape[0]), int(frame.shape[1]))
        if self.shape is None:
            self.shape, self.dtype = size, frame.dtype
        elif size != self.shape:
            raise DecodeError(f"{self.codec.name}: frames differ in size: {sorted({self.shape, size})}")
        elif frame.dtype != self.dtype:
            raise DecodeError(f"{self.codec.name}: frames differ in type: {self.dtype}, {frame.dtype}")
        if self.deblur is not None:
            frame = self.deblur.restored(frame)
        self._consume(self.added, frame)
        self.saturation.add(frame)
        if self.spill is not None:
            self.spill.add(self.added, frame)
        self.added += 1

    def finish(self) -> Correspondence:
        expected = self.codec.frame_count
        if self.added != expected:
            raise DecodeError(f"{self.codec.name}: expected {expected} frames, got {self.added}")
        corr = self.saturation.honoured(self._finish())
        if self.spill is not None:
            corr = self.spill.honoured(corr)
        return dataclasses.replace(corr, full_scale=self.full_scale)

    @abc.abstractmethod
    def _consume(self, index: int, frame: np.ndarray) -> None:
        """Frame `index` has arrived (0 is the white frame and 1 the dark one, for every codec but
        cued_phase, which shows neither)."""

    @abc.abstractmethod
    def _finish(self) -> Correspondence: ...


def decode_streamed(codec: Codec, frames: list[np.ndarray], full_scale: int) -> Correspondence:
    """`frames` fed one by one to the codec's stream, as a scan decodes them."""
    stream = codec.stream(full_scale)
    for frame in frames:
        stream.add(frame)
    return stream.finish()


class BufferedStream(FrameStream):
    """Keeps the frames and decodes them with the batch decoder at the end (codecs whose work
    cannot start before the last frame)."""

    def __init__(self, codec: Codec, full_scale: int) -> None:
        super().__init__(codec, full_scale)
        self._frames: list[np.ndarray] = []

    def _consume(self, index: int, frame: np.ndarray) -> None:
        self._frames.append(frame)

    def _finish(self) -> Correspondence:
        frames, self._frames = self._frames, []
        return self.codec.decode(frames, self.full_scale)


def integer_frame(codec: Codec, frame: np.ndarray) -> np.ndarray:
    """A frame as one channel of unsigned integer counts, as the integer decoders read it."""
    if frame.dtype not in (np.uint8, np.uint16):
        raise DecodeError(f"{codec.name}: frames must be 8- or 16-bit counts, got {frame.dtype}")
    return luminance(frame)


class GrayBits:
    """A Gray code read one (pattern, inverse) pair at a time, most significant bit first, in
    integer counts: one pass over the two frames per pair (rig.kernels.dense.gray_pair), a band of rows per
    thread. The binary value's bits so far give the XOR of the Gray bits, so the pass reads and
    writes only the value and the two weakest strengths.

    Gives what rig.patterns.graycode.read_bits gives: the binary value, and the second-smallest
    |pattern - inverse| over the bits (in counts). Its images are made when the first pair comes,
    in the frames' size and type."""

    def __init__(self, bits: int) -> None:
        if not 1 <= bits <= 16:
            raise ValueError(f"1 to 16 bits, got {bits}")
        self.bits = bits
        self.read = 0
        self._held: np.ndarray | None = None  # a pattern waiting for its inverse
        self._value: np.ndarray | None = None
        self._weakest: np.ndarray | None = None
        self._second: np.ndarray | None = None

    def take(self, image: np.ndarray) -> bool:
        """The next frame of the code: a pattern is held until its inverse comes and the pair is
        read. True once every bit is read."""
        if self._held is None:
            self._held = image
        else:
            self.add(self._held, image)
            self._held = None
        return self.read == self.bits

    def add(self, pattern: np.ndarray, inverse: np.ndarray) -> None:
        if self.read >= self.bits:
            raise ValueError("every bit has been read")
        shift = self.bits - 1 - self.read
        if self._value is None:
            shape, top = pattern.shape[:2], np.iinfo(pattern.dtype).max
            self._value = np.zeros(shape, np.uint16)
            self._weakest, self._second = np.full(shape, top, pattern.dtype), np.full(shape, top, pattern.dtype)
        value, weakest, second = self._value, self._weakest, self._second
        in_row_strips(
            value.shape[0],
            lambda rows: kernels.gray_pair(pattern, inverse, shift, value, weakest, second, rows.start, rows.stop),
        )
        self.read += 1

    def value(self) -> np.ndarray:
        """The binary value (uint16)."""
        assert self._value is not None, "no pair read"
        return self._value

    def strength(self) -> np.ndarray:
        """The second-smallest |pattern - inverse| over the bits, in counts (the frames' type)."""
        assert self._second is not None, "no pair read"
        return self._second


class DenseBase:
    """What the streams of per-pixel codecs share: the white and dark frames (texture, lit mask,
    contrast), the validity mask each coded axis narrows, the counts, and the Correspondence."""

    def __init__(self, codec: Codec, full_scale: int, keep_contrast: bool = True) -> None:
        self.codec = codec
        self.full_scale = full_scale
        self.keep_contrast = keep_contrast
        self.texture: np.ndarray | None = None
        self.lit: np.ndarray | None = None
        self.valid: np.ndarray | None = None
        self.counts: dict[str, int] = {}
        self._white: np.ndarray | None = None
        self._contrast: np.ndarray | None = None
        self._current: list[np.ndarray] = []  # coordinates already NaN wherever valid is False now

    def coded_frame(self, index: int, frame: np.ndarray) -> np.ndarray | None:
        """Frame `index` of the codec's sequence: the white (0) and dark (1) frames are taken here
        (None); a coded frame comes back in integer counts (integer_frame)."""
        if index < 2:
            self.consume(index, frame)
            return None
        return integer_frame(self.codec, frame)

    def consume(self, index: int, frame: np.ndarray) -> None:
        """The white (0) or the dark (1) frame."""
        image = integer_frame(self.codec, frame)
        if index == 0:
            self.texture, self._white = frame, image
            return
        assert self._white is not None
        white, scale = self._white, np.float32(1.0 / self.full_scale)
        contrast, lit, valid = (
            np.empty(image.shape if self.keep_contrast else (0, 0), np.float32),
            np.empty(image.shape, bool),
            np.empty(image.shape, bool),
        )
        threshold, counts = np.float32(self.codec.params.black_threshold), []  # as numpy compares float32
        in_row_strips(
            image.shape[0],
            lambda rows: counts.append(
                kernels.contrast_and_lit(white, image, scale, threshold, contrast, lit, valid, rows.start, rows.stop)
            ),
        )
        self._contrast, self._white, self.lit, self.valid = contrast, None, lit, valid
        self.counts["lit"] = sum(counts)

    def contrast(self) -> np.ndarray:
        assert self._contrast is not None and self.keep_contrast
        return self._contrast

    def accept(self, reader: GrayBits, extent: int, min_strength: int, count_name: str) -> np.ndarray:
        """A Gray-coded axis read whole: its coordinate (float32, NaN where not valid), the pixels
        with a weak bit or a code beyond `extent` dropped, in one pass (rig.kernels.dense.gray_accept)."""
        value, strength, lit, valid = reader.value(), reader.strength(), self.lit, self.valid
        assert lit is not None and valid is not None
        coordinate, dropped = np.empty(value.shape, np.float32), []
        arrays = (value, strength, min_strength, extent, lit, valid, coordinate)
        in_row_strips(value.shape[0], lambda rows: dropped.append(kernels.gray_accept(*arrays, rows.start, rows.stop)))
        self.narrowed(count_name, sum(dropped), coordinate)
        return coordinate

    def narrowed(self, count_name: str, count: int, coordinate: np.ndarray) -> None:
        """A compiled pass has narrowed `valid` itself, counting `count`, and written `coordinate`
        NaN wherever it is not valid now (coordinates written before are stale)."""
        self.counts[count_name] = count
        self._current = [coordinate]

    def correspondence(self, coords: dict[str, np.ndarray], quality: np.ndarray) -> Correspondence:
        """The Correspondence, coordinates NaN where not valid (as LineCodec.correspondence)."""
        valid, texture = self.valid, self.texture
        assert valid is not None and texture is not None
        nan = np.float32(np.nan)
        stale = [c for c in coords.values() if not any(c is current for current in self._current)]

        def strip(rows: slice) -> None:
            invalid = ~valid[rows]
            for coordinate in stale:
                np.copyto(coordinate[rows], nan, where=invalid)

        in_row_strips(valid.shape[0], strip)
        self.counts["decoded"] = int(np.count_nonzero(valid))
        return Correspondence(
            valid=valid, quality=quality, texture=texture, u=coords.get("u"), v=coords.get("v"), counts=self.counts
        )
