"""Gray-code bit planes with inverses, shared by the codecs that use them."""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rig.patterns.correspondence import NormalizedFrames


def bit_count(values: int) -> int:
    """Bits needed to give `values` distinct codes."""
    return max(1, math.ceil(math.log2(values)))


def gray_planes(index: np.ndarray, bits: int) -> list[np.ndarray]:
    """Bit planes of gray(index), most significant first, as bool arrays of index's shape."""
    return list(_gray_planes(index, bits))


def _gray_planes(index: np.ndarray, bits: int) -> Iterator[np.ndarray]:
    gray = index >> 1
    gray ^= index  # in place: one index-sized temporary, not two
    for b in range(bits - 1, -1, -1):
        yield ((gray >> b) & 1).astype(bool)


def gray_images(index: np.ndarray, bits: int) -> Iterator[np.ndarray]:
    """planes_with_inverses(gray_planes(index, bits)) one image at a time, each plane made as its
    turn comes."""
    for plane in _gray_planes(index, bits):
        yield from planes_with_inverses([plane])


def planes_with_inverses(planes: list[np.ndarray]) -> list[np.ndarray]:
    """Pattern images: for each plane, the plane and its inverse, as uint8 0/255."""
    out = []
    for plane in planes:
        img = plane.astype(np.uint8) * 255
        out += [img, 255 - img]
    return out


def decode_gray(frames: NormalizedFrames, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """Decode `bits` (pattern, inverse) frame pairs, MSB first (see read_bits)."""
    return read_bits((frames.difference(2 * b, 2 * b + 1) for b in range(bits)), gray=True)


def read_bits(differences: Iterable[np.ndarray], gray: bool) -> tuple[np.ndarray, np.ndarray]:
    """The value spelled by bit frames, MSB first, each given as its difference from its reference
    (its inverse, or a threshold): a bit is 1 where the difference is positive.

    Returns the binary value (int32; `gray`: the bits are a Gray code) and the smallest |difference|
    over the bits for each pixel, except the single smallest one: along a Gray code only one bit
    changes at any stripe edge, so one weak bit is expected there and is no reason to reject a pixel.
    """
    value = prefix = weakest = second = None
    for difference in differences:
        if value is None:
            value, prefix = np.zeros(difference.shape, np.int32), np.zeros(difference.shape, np.int32)
            weakest = second = np.full(difference.shape, np.inf, dtype=np.float32)
        bit = (difference > 0).astype(np.int32)
        if gray:
            prefix ^= bit  # binary bit = XOR of the Gray bits so far
            bit = prefix
        value = (value << 1) | bit
        strength = np.abs(difference)
        second = np.minimum(second, np.maximum(weakest, strength))
        weakest = np.minimum(weakest, strength)
    if value is None:
        raise ValueError("no bit frames")
    return value, second
