"""Decompression bombs: small files that decode to huge images, written without holding the pixels."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

ROWS_PER_CALL = 64  # rows handed to zlib at a time: a few MB at most, whatever the image


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def write_png_bomb(path: Path, width: int, height: int, bit_depth: int = 16) -> int:
    """A valid grey PNG of `width` x `height` at `bit_depth` (1, 2, 4, 8 or 16), every pixel 0,
    written to `path` a few rows at a time (about 1/1000 of the decoded size for zeros); returns the
    file's size in bytes."""
    if bit_depth not in (1, 2, 4, 8, 16):
        raise ValueError(f"bit_depth {bit_depth}: a grey PNG has 1, 2, 4, 8 or 16 bits")
    row = bytes(1 + (width * bit_depth + 7) // 8)  # filter type 0 (none), then the row's zero bytes
    rows = row * min(ROWS_PER_CALL, height)
    packer = zlib.compressobj(9)
    with path.open("wb") as out:
        out.write(b"\x89PNG\r\n\x1a\n")
        out.write(_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, bit_depth, 0, 0, 0, 0)))
        for start in range(0, height, ROWS_PER_CALL):
            count = min(ROWS_PER_CALL, height - start)
            data = packer.compress(rows if count == ROWS_PER_CALL else row * count)
            if data:  # one IDAT chunk per piece: a decoder joins them
                out.write(_chunk(b"IDAT", data))
        out.write(_chunk(b"IDAT", packer.flush()))
        out.write(_chunk(b"IEND", b""))
        return out.tell()
