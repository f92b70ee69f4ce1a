"""Gray-code bit planes with inverses, shared by the codecs that use them."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def bit_count(values: int) -> int:
    """Bits needed to give `values` distinct codes."""
    return max(1, math.ceil(math.log2(values)))


def gray_planes(index: np.ndarray, bits: int) -> list[np.ndarray]:
    """Bit planes of gray(index), most significant first, as bool arrays of index's shape."""
    gray = index ^ (index >> 1)
    return [((gray >> b) & 1).astype(bool) for b in range(bits - 1, -1, -1)]


def planes_with_inverses(planes: list[np.ndarray]) -> list[np.ndarray]:
    """Pattern images: for each plane, the plane and its inverse, as uint8 0/255."""
    out = []
    for plane in planes:
        img = plane.astype(np.uint8) * 255
        out += [img, 255 - img]
    return out


def decode_gray(frames: Sequence[np.ndarray], bits: int) -> tuple[np.ndarray, np.ndarray]:
    """Decode `bits` (pattern, inverse) frame pairs, MSB first.

    Returns the binary value (int32) and the smallest |pattern - inverse| over the bits for each
    pixel, except the single smallest one: along a Gray code only one bit changes at any stripe
    edge, so one weak bit is expected there and is no reason to reject a pixel.
    """
    shape = frames[0].shape
    value = np.zeros(shape, dtype=np.int32)
    bit = np.zeros(shape, dtype=np.int32)
    weakest = np.full(shape, np.inf, dtype=np.float32)
    second = np.full(shape, np.inf, dtype=np.float32)
    for b in range(bits):
        diff = frames[2 * b] - frames[2 * b + 1]
        g = (diff > 0).astype(np.int32)
        bit ^= g  # binary bit = XOR of gray bits so far (prefix XOR)
        value = (value << 1) | bit
        strength = np.abs(diff)
        second = np.minimum(second, np.maximum(weakest, strength))
        weakest = np.minimum(weakest, strength)
    return value, second
