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
from typing import TYPE_CHECKING

import cv2
import numpy as np

from rig.errors import DecodeError
from rig.patterns.base import Correspondence, luminance
from rig.workers import in_row_strips

if TYPE_CHECKING:
    from rig.patterns.base import Codec


class FrameStream(abc.ABC):
    """One (projector, camera) pair's frames decoded as they arrive: `add` each frame in pattern
    order, then `finish` for the Correspondence. Raises DecodeError for a frame too many, too few,
    or of another size than the first."""

    def __init__(self, codec: Codec, full_scale: int) -> None:
        self.codec = codec
        self.full_scale = full_scale
        self.added = 0
        self.shape: tuple[int, int] | None = None

    def add(self, frame: np.ndarray) -> None:
        expected = self.codec.frame_count
        if self.added >= expected:
            raise DecodeError(f"{self.codec.name}: expected {expected} frames, got more")
        size = (int(frame.shape[0]), int(frame.shape[1]))
        if self.shape is None:
            self.shape = size
        elif size != self.shape:
            raise DecodeError(f"{self.codec.name}: frames differ in size: {sorted({self.shape, size})}")
        self._consume(self.added, frame)
        self.added += 1

    def finish(self) -> Correspondence:
        expected = self.codec.frame_count
        if self.added != expected:
            raise DecodeError(f"{self.codec.name}: expected {expected} frames, got {self.added}")
        return dataclasses.replace(self._finish(), full_scale=self.full_scale)

    @abc.abstractmethod
    def _consume(self, index: int, frame: np.ndarray) -> None:
        """Frame `index` (0 is the white frame, 1 the dark one) has arrived."""

    @abc.abstractmethod
    def _finish(self) -> Correspondence: ...


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
    integer counts (one pass of a few OpenCV operations per pair, on row strips in parallel).

    Gives what rig.patterns.graycode.read_bits gives: the binary value, and the second-smallest
    |pattern - inverse| over the bits (in counts)."""

    def __init__(self, shape: tuple[int, int], bits: int, dtype: np.dtype) -> None:
        if not 1 <= bits <= 16:
            raise ValueError(f"1 to 16 bits, got {bits}")
        self.bits = bits
        self.read = 0
        self._rows = shape[0]
        self._prefix = np.zeros(shape, np.uint8)  # 255 where the binary value's bit so far is 1
        self._bytes = [np.zeros(shape, np.uint8) for _ in range((bits + 7) // 8)]  # the value, low byte first
        top = np.iinfo(dtype).max
        self._weakest = np.full(shape, top, dtype)
        self._second = np.full(shape, top, dtype)

    def add(self, pattern: np.ndarray, inverse: np.ndarray) -> None:
        if self.read >= self.bits:
            raise ValueError("every bit has been read")
        weight = self.bits - 1 - self.read
        target, mask = self._bytes[weight // 8], 1 << (weight % 8)

        def strip(rows: slice) -> None:
            a, b = pattern[rows], inverse[rows]
            prefix, byte = self._prefix[rows], target[rows]
            cv2.bitwise_xor(prefix, cv2.compare(a, b, cv2.CMP_GT), dst=prefix)  # binary bit: XOR of the Gray bits
            cv2.bitwise_or(byte, cv2.bitwise_and(prefix, mask), dst=byte)
            strength = cv2.absdiff(a, b)
            weakest, second = self._weakest[rows], self._second[rows]
            cv2.min(second, cv2.max(weakest, strength), dst=second)
            cv2.min(weakest, strength, dst=weakest)

        in_row_strips(self._rows, strip)
        self.read += 1

    def value(self) -> np.ndarray:
        """The binary value (uint8 up to 8 bits, uint16 beyond)."""
        if len(self._bytes) == 1:
            return self._bytes[0]
        value = self._bytes[1].astype(np.uint16)
        value <<= 8
        value |= self._bytes[0]
        return value

    def value_into(self, out: np.ndarray, rows: slice) -> None:
        """The binary value of `rows` written into `out[rows]` (a float array of the frame's shape)."""
        np.copyto(out[rows], self._bytes[0][rows])
        if len(self._bytes) > 1:
            out[rows] += self._bytes[1][rows] * out.dtype.type(256)

    def strength(self) -> np.ndarray:
        """The second-smallest |pattern - inverse| over the bits, in counts (the frames' type)."""
        return self._second


class DenseBase:
    """What the streams of per-pixel codecs share: the white and dark frames (texture, lit mask,
    contrast), the validity mask each coded axis narrows, the counts, and the Correspondence."""

    def __init__(self, codec: Codec, full_scale: int) -> None:
        self.codec = codec
        self.full_scale = full_scale
        self.texture: np.ndarray | None = None
        self.lit: np.ndarray | None = None
        self.valid: np.ndarray | None = None
        self.counts: dict[str, int] = {}
        self._white: np.ndarray | None = None
        self._contrast: np.ndarray | None = None

    def consume(self, index: int, frame: np.ndarray) -> None:
        """The white (0) or the dark (1) frame."""
        image = integer_frame(self.codec, frame)
        if index == 0:
            self.texture, self._white = frame, image
            return
        assert self._white is not None
        white, scale = self._white, np.float32(1.0 / self.full_scale)
        contrast, lit = np.empty(image.shape, np.float32), np.empty(image.shape, bool)
        threshold = self.codec.params.black_threshold

        def strip(rows: slice) -> None:
            # As the batch decoder computes it (each frame in fractions, then the difference): the same floats.
            np.multiply(white[rows], scale, out=contrast[rows], dtype=np.float32)
            contrast[rows] -= image[rows].astype(np.float32) * scale
            np.greater_equal(contrast[rows], threshold, out=lit[rows])

        in_row_strips(image.shape[0], strip)
        self._contrast, self._white, self.lit, self.valid = contrast, None, lit, lit.copy()
        self.counts["lit"] = int(np.count_nonzero(self.lit))

    def contrast(self) -> np.ndarray:
        assert self._contrast is not None
        return self._contrast

    def narrow(self, ok: np.ndarray, count_name: str | None = None, counted: np.ndarray | None = None) -> None:
        """Keep only the pixels `ok`; `count_name` counts the lit pixels `counted` (by default, those
        `ok` drops)."""
        assert self.valid is not None and self.lit is not None
        self.valid &= ok
        if count_name is not None:
            self.counts[count_name] = int(np.count_nonzero(self.lit & (~ok if counted is None else counted)))

    def accept(self, reader: GrayBits, extent: int, min_strength: int, count_name: str) -> np.ndarray:
        """A Gray-coded axis read whole: its coordinate (float32), the pixels with a weak bit or a
        code beyond `extent` dropped."""
        strength = reader.strength()
        ok = np.empty(strength.shape, bool)
        coordinate = np.empty(strength.shape, np.float32)

        def strip(rows: slice) -> None:
            reader.value_into(coordinate, rows)
            np.greater_equal(strength[rows], min_strength, out=ok[rows])
            ok[rows] &= coordinate[rows] < extent

        in_row_strips(strength.shape[0], strip)
        self.narrow(ok, count_name)
        return coordinate

    def correspondence(self, coords: dict[str, np.ndarray], quality: np.ndarray) -> Correspondence:
        """The Correspondence, coordinates NaN where not valid (as LineCodec.correspondence)."""
        valid, texture = self.valid, self.texture
        assert valid is not None and texture is not None
        nan = np.float32(np.nan)

        def strip(rows: slice) -> None:
            invalid = ~valid[rows]
            for coordinate in coords.values():
                np.copyto(coordinate[rows], nan, where=invalid)

        in_row_strips(valid.shape[0], strip)
        self.counts["decoded"] = int(np.count_nonzero(valid))
        return Correspondence(
            valid=valid, quality=quality, texture=texture, u=coords.get("u"), v=coords.get("v"), counts=self.counts
        )
