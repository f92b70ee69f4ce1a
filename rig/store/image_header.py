"""An image's size from its header alone (PNG, BMP, TIFF, JPEG): a few bounded reads, never the
pixels, so that a small file that decodes to gigabytes (a decompression bomb) is refused before
OpenCV allocates them."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rig.errors import FramesError

MAX_HEADER_BYTES = 8 * 1024  # all the reads of one header together: a TIFF's first IFD is the largest
MAX_IFD_ENTRIES = 256  # the tags needed are numbered 256..277; a real IFD has a few dozen entries
JPEG_WALK_BYTES = 1 << 20  # the frame header must start this early: APP segments (Exif, ICC) come first
JPEG_MAX_SEGMENTS = 256  # 4 bytes read of each: its marker and length
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}  # SOF0..SOF15 less DHT, JPG, DAC
_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})  # TEM, RST0..7: markers without a length
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}  # colour type -> samples (a palette index is one)
_PNG_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}
_BMP_DIB_SIZES = (12, 16, 40, 52, 56, 64, 108, 124)  # CORE, OS/2 2.x (short, long), INFO, V2, V3, V4, V5
_TIFF_TYPES = {3: ("H", 2), 4: ("I", 4), 16: ("Q", 8)}  # SHORT, LONG, LONG8 (BigTIFF)


@dataclass(frozen=True)
class ImageHeader:
    width: int
    height: int
    channels: int  # samples per pixel as stored (a palette index counts as one)
    bits_per_sample: int
    format: str  # "PNG", "BMP", "TIFF", "BigTIFF", "JPEG"

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    @property
    def pixels(self) -> int:
        return self.width * self.height


class _Reader:
    """Reads at offsets of a file or of bytes, all of them together within MAX_HEADER_BYTES."""

    def __init__(self, name: str, read_at: Callable[[int, int], bytes]) -> None:
        self.name, self._read_at, self._spent = name, read_at, 0

    def peek(self, size: int) -> bytes:
        """The first `size` bytes, or fewer in a shorter file."""
        self._spent += size
        return self._read_at(0, size)

    def at(self, offset: int, size: int, what: str) -> bytes:
        self._spent += size
        if self._spent > MAX_HEADER_BYTES:
            raise self.error(f"its {what} would take the header beyond {MAX_HEADER_BYTES} bytes")
        data = self._read_at(offset, size) if offset < 1 << 48 else b""  # far beyond any file: no seek
        if len(data) < size:
            raise self.error(f"cut short: the file ends within its {what} (byte {offset + len(data)})")
        return data

    def error(self, reason: str) -> FramesError:
        return FramesError(f"{self.name}: not an image slrig can read ({reason})")


def read_image_header(path: Path) -> ImageHeader:
    """The header of the image file `path`; FramesError naming it if the header is unknown, cut short
    or invalid, or the file cannot be read."""
    try:
        with path.open("rb") as file:

            def read_at(offset: int, size: int) -> bytes:
                file.seek(offset)
                return file.read(size)

            return _parse(_Reader(str(path), read_at))
    except OSError as exc:
        raise FramesError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def image_header_bytes(data: bytes, name: str = "upload") -> ImageHeader:
    """The header of an image held in memory (an upload); FramesError naming `name` as image_header does."""
    return _parse(_Reader(name, lambda offset, size: data[offset : offset + size]))


def check_image_size(header: ImageHeader, name: str, expected: tuple[int, int] | None, max_pixels: int) -> None:
    """FramesError naming `name`, its size and the limit if the image has more than `max_pixels`
    pixels, or is not `expected` (width, height) when that is given."""
    w, h = header.size
    if header.pixels > max_pixels:
        raise FramesError(
            f"{name}: {w}x{h} pixels ({header.pixels / 1e6:.1f} megapixels), "
            f"more than the limit of {max_pixels} ({max_pixels / 1e6:.1f} megapixels)"
        )
    if expected is not None and header.size != tuple(expected):
        raise FramesError(f"{name}: {w}x{h} pixels, expected {expected[0]}x{expected[1]}")


def _parse(reader: _Reader) -> ImageHeader:
    head = reader.peek(8)  # the signature
    if head.startswith(b"\x89PNG\r\n\x1a\n"):
        found = _png(reader)
    elif head.startswith(b"BM"):
        found = _bmp(reader)
    elif head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        found = _tiff(reader, "<" if head[:2] == b"II" else ">")
    elif head.startswith(b"\xff\xd8\xff"):
        found = _jpeg(reader)
    else:
        raise reader.error(f"not PNG, BMP, TIFF or JPEG: it begins {head[:8]!r}")
    if found.width <= 0 or found.height <= 0 or found.channels <= 0 or found.bits_per_sample <= 0:
        raise reader.error(f"its {found.format} header gives {found.width}x{found.height}, {found.channels} channels")
    return found


def _png(reader: _Reader) -> ImageHeader:
    chunk = reader.at(8, 8 + 13 + 4, "IHDR chunk")  # the first chunk, by the spec
    length, kind = struct.unpack(">I4s", chunk[:8])
    if kind != b"IHDR" or length != 13 or zlib.crc32(chunk[4:21]) != struct.unpack(">I", chunk[21:])[0]:
        raise reader.error("its PNG header (IHDR) is missing or damaged")
    width, height, depth, colour = struct.unpack(">IIBB", chunk[8:18])
    if depth not in _PNG_DEPTHS.get(colour, ()):
        raise reader.error(f"PNG colour type {colour} at {depth} bits is not a valid PNG")
    return ImageHeader(width, height, _PNG_CHANNELS[colour], depth, "PNG")


def _bmp(reader: _Reader) -> ImageHeader:
    (dib,) = struct.unpack("<I", reader.at(14, 4, "DIB header size"))
    if dib not in _BMP_DIB_SIZES:
        raise reader.error(f"a BMP DIB header of {dib} bytes is not one of {', '.join(map(str, _BMP_DIB_SIZES))}")
    if dib == 12:  # BITMAPCOREHEADER: unsigned 16-bit sizes
        width, height, _, bpp = struct.unpack("<HHHH", reader.at(18, 8, "BMP core header"))
    else:  # the same first fields in every later header; a negative height is a top-down image
        width, height, _, bpp = struct.unpack("<iiHH", reader.at(18, 12, "BMP info header"))
        height = abs(height)
    if bpp not in (1, 4, 8, 16, 24, 32):
        raise reader.error(f"a BMP of {bpp} bits per pixel")
    channels, bits = {16: (3, 5), 24: (3, 8), 32: (4, 8)}.get(bpp, (1, bpp))  # 16: RGB 555 or 565
    return ImageHeader(width, height, channels, bits, "BMP")


def _tiff(reader: _Reader, order: str) -> ImageHeader:
    big = reader.at(2, 2, "TIFF header") == struct.pack(order + "H", 43)  # BigTIFF: 64-bit offsets and counts
    offset_format, entry_size, inline = (order + "Q", 20, 8) if big else (order + "I", 12, 4)
    if big and reader.at(4, 4, "BigTIFF header") != struct.pack(order + "HH", 8, 0):
        raise reader.error("its BigTIFF header gives an offset size other than 8")
    (ifd,) = struct.unpack(offset_format, reader.at(8 if big else 4, inline, "TIFF header"))
    (count,) = struct.unpack(order + ("Q" if big else "H"), reader.at(ifd, inline if big else 2, "first IFD"))
    if count > MAX_IFD_ENTRIES:  # not truncated: a tag past the cut could be the one a decoder reads
        raise reader.error(f"its first TIFF IFD has {count} entries (at most {MAX_IFD_ENTRIES})")
    entries = reader.at(ifd + (8 if big else 2), count * entry_size, "first IFD")
    tags: dict[int, tuple[int, ...]] = {}
    for start in range(0, len(entries), entry_size):
        tag, kind = struct.unpack(order + "HH", entries[start : start + 4])
        if tag not in (256, 257, 258, 277):
            continue
        # A size given twice, or in a type read here otherwise than by a decoder, could hide the
        # size the decoder uses (libtiff keeps the first of repeated tags): refused, not guessed.
        if tag in tags:
            raise reader.error(f"its first TIFF IFD gives tag {tag} twice")
        if kind not in _TIFF_TYPES:
            raise reader.error(f"TIFF tag {tag} has type {kind}, not SHORT, LONG or LONG8")
        (n,) = struct.unpack(offset_format, entries[start + 4 : start + 4 + inline])
        code, size = _TIFF_TYPES[kind]
        if not 1 <= n <= 16:  # one value each; BitsPerSample one per sample
            raise reader.error(f"TIFF tag {tag} has {n} values")
        raw = entries[start + 4 + inline : start + 4 + 2 * inline]
        if n * size > inline:  # the values are elsewhere, at the offset the entry holds
            raw = reader.at(struct.unpack(offset_format, raw)[0], n * size, f"TIFF tag {tag}")
        tags[tag] = struct.unpack(f"{order}{n}{code}", raw[: n * size])
    if 256 not in tags or 257 not in tags:
        raise reader.error("its first TIFF IFD has no ImageWidth or ImageLength")
    samples = tags.get(277, (1,))[0]  # the spec's defaults: one sample of one bit
    return ImageHeader(tags[256][0], tags[257][0], samples, max(tags.get(258, (1,))), "BigTIFF" if big else "TIFF")


def _jpeg(reader: _Reader) -> ImageHeader:
    offset = 2  # after SOI
    for _ in range(JPEG_MAX_SEGMENTS):
        if offset > JPEG_WALK_BYTES:
            break
        mark, code = reader.at(offset, 2, "JPEG marker")
        if mark != 0xFF:
            raise reader.error(f"no JPEG marker at byte {offset}")
        if code == 0xFF or code in _STANDALONE:  # a fill byte, or a marker with no segment
            offset += 1 if code == 0xFF else 2
            continue
        if code in (0xD9, 0xDA):  # end of image, start of scan
            raise reader.error("its JPEG data come before a frame header (SOF)")
        (length,) = struct.unpack(">H", reader.at(offset + 2, 2, "JPEG segment length"))
        if length < 2:
            raise reader.error(f"a JPEG segment of length {length} at byte {offset}")
        if code in _SOF:
            precision, height, width, components = struct.unpack(">BHHB", reader.at(offset + 4, 6, "JPEG SOF"))
            if height == 0:  # the height comes later, in a DNL segment after the first scan
                raise reader.error("its JPEG frame header leaves the height to a DNL segment")
            return ImageHeader(width, height, components, precision, "JPEG")
        offset += 2 + length
    raise reader.error(
        f"no JPEG frame header (SOF) in its first {JPEG_MAX_SEGMENTS} segments or {JPEG_WALK_BYTES} bytes"
    )
