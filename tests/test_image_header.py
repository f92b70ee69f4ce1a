"""Image sizes read from headers alone (rig.store.image_header), without decoding; bombs in a
frames folder: tests/test_frame_bombs.py."""

from __future__ import annotations

import re
import struct
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from rig.errors import FramesError
from rig.store.image_header import ImageHeader, check_image_size, image_header_bytes, read_image_header

BOMB_SIZE = 20000  # 20000 x 20000 at 16 bits: 800 MB of pixels in a 0.78 MB file
SIZES = [(1, 1), (7, 5), (640, 480), (3, 1000)]
# (suffix, numpy depth, channels) that OpenCV writes as such: BMP and JPEG only 8-bit, JPEG no alpha
WRITTEN = [
    (suffix, depth, channels)
    for suffix in (".png", ".tif", ".bmp", ".jpg")
    for depth in (np.uint8, np.uint16)
    for channels in (1, 3, 4)
    if not (suffix in (".bmp", ".jpg") and depth == np.uint16) and not (suffix == ".jpg" and channels == 4)
]


def _image(size: tuple[int, int], depth: type, channels: int) -> np.ndarray:
    shape = (size[1], size[0]) if channels == 1 else (size[1], size[0], channels)
    top = 65535 if depth == np.uint16 else 255
    return np.random.default_rng(size[0] * size[1]).integers(0, top, shape).astype(depth)


def _as_read(image: np.ndarray) -> tuple[int, int, int, int]:
    """(width, height, channels, bits per sample) of what OpenCV decoded."""
    return image.shape[1], image.shape[0], 1 if image.ndim == 2 else image.shape[2], 8 * image.itemsize


def _fields(header: ImageHeader) -> tuple[int, int, int, int]:
    return header.width, header.height, header.channels, header.bits_per_sample


@pytest.mark.parametrize(("suffix", "depth", "channels"), WRITTEN)
def test_the_header_of_what_opencv_writes_is_what_opencv_reads(
    tmp_path: Path, suffix: str, depth: type, channels: int
) -> None:
    for size in SIZES:
        path = tmp_path / f"image_{size[0]}x{size[1]}{suffix}"
        assert cv2.imwrite(str(path), _image(size, depth, channels))
        header = read_image_header(path)
        assert _fields(header) == _as_read(cv2.imread(str(path), cv2.IMREAD_UNCHANGED)), path.name
        assert header.format == {".png": "PNG", ".tif": "TIFF", ".bmp": "BMP", ".jpg": "JPEG"}[suffix]
        assert image_header_bytes(path.read_bytes()) == header
        assert (header.size, header.pixels) == (size, size[0] * size[1])


def test_a_progressive_jpeg_and_one_whose_frame_header_comes_late(tmp_path: Path) -> None:
    """SOF2, and a frame header behind long APP and comment segments and fill bytes; one beyond
    JPEG_WALK_BYTES is refused rather than walked to."""
    path = tmp_path / "progressive.jpg"
    assert cv2.imwrite(str(path), _image((45, 31), np.uint8, 3), [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
    assert _fields(read_image_header(path)) == (45, 31, 3, 8) == _as_read(cv2.imread(str(path), cv2.IMREAD_UNCHANGED))
    plain = cv2.imencode(".jpg", _image((45, 31), np.uint8, 1))[1].tobytes()
    comment = b"\xff\xfe" + struct.pack(">H", 65535) + bytes(65533)
    exif = b"\xff\xe1" + struct.pack(">H", 30002) + b"Exif\0\0" + bytes(29994)
    late = plain[:2] + exif + comment * 3 + b"\xff\xff\xff" + plain[2:]
    path.write_bytes(late)
    assert _fields(read_image_header(path)) == (45, 31, 1, 8) == _as_read(cv2.imread(str(path), cv2.IMREAD_UNCHANGED))
    path.write_bytes(plain[:2] + comment * 17 + plain[2:])  # 1.1 MB of comments before the frame header
    with pytest.raises(FramesError, match=re.escape(f"{path}: not an image slrig can read (no JPEG frame header")):
        read_image_header(path)


def _tiff(width: int, height: int, order: str, big: bool, long_sizes: bool, samples: int, bits: int) -> bytes:
    """An uncompressed TIFF (one strip), classic or BigTIFF, little- or big-endian, its sizes SHORT or LONG."""
    inline, offset_code = (8, "Q") if big else (4, "I")
    start = 16 if big else 8
    pixels = bytes(width * height * samples * bits // 8)
    size, offset = ((4, "I") if long_sizes else (3, "H")), ((16, "Q") if big else (4, "I"))
    entries = [  # tag, type, code, values: in ascending tag order, as the spec asks
        (256, *size, [width]),
        (257, *size, [height]),
        (258, 3, "H", [bits] * samples),  # BitsPerSample: stored after the pixels if it does not fit inline
        (259, 3, "H", [1]),
        (262, 3, "H", [1 if samples == 1 else 2]),
        (273, *offset, [start]),
        (277, 3, "H", [samples]),
        (278, 4, "I", [height]),
        (279, *offset, [len(pixels)]),
        (284, 3, "H", [1]),
    ]
    elsewhere = struct.pack(f"{order}{samples}H", *[bits] * samples)
    elsewhere = elsewhere if len(elsewhere) > inline else b""
    ifd = start + len(pixels) + len(elsewhere)
    ifd += ifd % 2  # an IFD starts on a word boundary
    magic = struct.pack(order + "HHHQ", 43, 8, 0, ifd) if big else struct.pack(order + "HI", 42, ifd)
    out = bytearray((b"II" if order == "<" else b"MM") + magic + pixels + elsewhere)
    out += bytes(ifd - len(out)) + struct.pack(order + ("Q" if big else "H"), len(entries))
    for tag, kind, code, values in entries:
        raw = struct.pack(f"{order}{len(values)}{code}", *values)
        raw = raw if len(raw) <= inline else struct.pack(order + offset_code, start + len(pixels))
        out += struct.pack(order + "HH" + offset_code, tag, kind, len(values)) + raw.ljust(inline, b"\0")
    return bytes(out + bytes(inline))  # no next IFD


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("big", [False, True])
@pytest.mark.parametrize("long_sizes", [False, True])
def test_tiff_either_byte_order_classic_or_big_sizes_short_or_long(
    tmp_path: Path, order: str, big: bool, long_sizes: bool
) -> None:
    for samples, bits in ((1, 8), (1, 16), (3, 8), (3, 16)):
        path = tmp_path / f"{samples}x{bits}.tif"
        path.write_bytes(_tiff(37, 11, order, big, long_sizes, samples, bits))
        header = read_image_header(path)
        assert _fields(header) == (37, 11, samples, bits) == _as_read(cv2.imread(str(path), cv2.IMREAD_UNCHANGED))
        assert header.format == ("BigTIFF" if big else "TIFF")


def _bmp(image: np.ndarray, dib: int, top_down: bool = False) -> bytes:
    """An 8-bit grey (grey palette) or 24-bit BMP with a DIB header of `dib` bytes."""
    height, width = image.shape[:2]
    bpp = 24 if image.ndim == 3 else 8
    entry = 3 if dib == 12 else 4  # the core header's palette has no reserved byte
    palette = b"".join(bytes((i, i, i, 0)[:entry]) for i in range(256)) if bpp == 8 else b""
    stride = (width * bpp // 8 + 3) & ~3
    pixels = b"".join(row.tobytes().ljust(stride, b"\0") for row in (image if top_down else image[::-1]))
    if dib == 12:
        header = struct.pack("<IHHHH", 12, width, height, 1, bpp)
    else:
        rows = -height if top_down else height
        header = struct.pack("<IiiHHII", dib, width, rows, 1, bpp, 0, len(pixels)).ljust(dib, b"\0")
    offset = 14 + len(header) + len(palette)
    return b"BM" + struct.pack("<IHHI", offset + len(pixels), 0, 0, offset) + header + palette + pixels


@pytest.mark.parametrize("dib", [12, 40, 52, 56, 64, 108, 124])
def test_bmp_of_every_dib_header_bottom_up_and_top_down(tmp_path: Path, dib: int) -> None:
    for channels in (1, 3):
        for top_down in (False, True) if dib != 12 else (False,):
            image = _image((21, 13), np.uint8, channels)
            path = tmp_path / f"{channels}_{top_down}.bmp"
            path.write_bytes(_bmp(image, dib, top_down))
            header = read_image_header(path)
            read = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            assert _fields(header) == (21, 13, channels, 8)
            assert header.size == (read.shape[1], read.shape[0])
            if dib != 12:  # OpenCV gives a core header's 24-bit colour as grey
                assert np.array_equal(read, image)


class _Counted:
    """A file that counts the bytes read from it."""

    def __init__(self, file: Any, counts: list[int]) -> None:
        self._file, self._counts = file, counts

    def __enter__(self) -> _Counted:
        return self

    def __exit__(self, *exc: object) -> None:
        self._file.close()

    def seek(self, offset: int) -> int:
        return self._file.seek(offset)

    def read(self, size: int) -> bytes:
        data = self._file.read(size)
        self._counts.append(len(data))
        return data


def test_only_the_header_is_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A few hundred bytes of files of megabytes; and a file cut short after its header still has one."""
    paths = [tmp_path / f"big{suffix}" for suffix in (".png", ".tif", ".bmp", ".jpg")]
    for path in paths:
        depth = np.uint8 if path.suffix in (".bmp", ".jpg") else np.uint16
        assert cv2.imwrite(str(path), _image((1200, 900), depth, 3))
    counts: list[int] = []
    opened = Path.open
    monkeypatch.setattr(Path, "open", lambda self, *a, **k: _Counted(opened(self, *a, **k), counts))
    for path in paths:
        counts.clear()
        assert read_image_header(path).size == (1200, 900)
        assert path.stat().st_size > 10**5 and sum(counts) < 1024, path.name
    monkeypatch.undo()
    for path, end in zip(paths[::2], (33, 30), strict=True):  # PNG: signature and IHDR; BMP: the DIB's first fields
        path.write_bytes(path.read_bytes()[:end])
        assert read_image_header(path).size == (1200, 900)


@pytest.mark.parametrize(
    ("suffix", "depth", "channels", "header_end"),
    [(".png", np.uint16, 1, 33), (".bmp", np.uint8, 3, 30), (".jpg", np.uint8, 1, None), (".tif", np.uint16, 3, None)],
)
def test_every_truncation_of_a_header_is_refused_naming_the_file(
    tmp_path: Path, suffix: str, depth: type, channels: int, header_end: int | None
) -> None:
    """Each prefix of a file either has the whole header or raises FramesError naming the file,
    never another exception; a prefix with the header has it whole."""
    path = tmp_path / f"frame_3{suffix}"
    assert cv2.imwrite(str(path), _image((50, 20), depth, channels))
    data, whole = path.read_bytes(), read_image_header(path)
    complete = []
    for end in range(len(data)):
        try:
            complete.append(image_header_bytes(data[:end], "cut") == whole)
        except FramesError as exc:
            assert str(exc).startswith("cut: not an image slrig can read ("), str(exc)
    assert all(complete) and len(complete) == len(data) - (header_end or len(data) - len(complete))
    for end in (0, 3, 9, 25):
        path.write_bytes(data[:end])
        with pytest.raises(FramesError, match=re.escape(f"{path}: not an image slrig can read (")):
            read_image_header(path)


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"", "not PNG, BMP, TIFF or JPEG: it begins b''"),
        (b"not a png at all", "not PNG, BMP, TIFF or JPEG: it begins b'not a pn'"),
        (bytes(100), "not PNG, BMP, TIFF or JPEG"),
        (b"\x89PNG\r\n\x1a\n" + bytes(4), "cut short: the file ends within its IHDR chunk (byte 12)"),
        (b"\x89PNG\r\n\x1a\n" + bytes(100), "its PNG header (IHDR) is missing or damaged"),
        (b"BM" + bytes(12) + struct.pack("<I", 41) + bytes(40), "a BMP DIB header of 41 bytes"),
        (b"BM" + bytes(12) + struct.pack("<IiiHH", 40, 0, 5, 1, 24) + bytes(30), "its BMP header gives 0x5"),
        (b"BM" + bytes(12) + struct.pack("<IiiHH", 40, 4, 5, 1, 7) + bytes(30), "a BMP of 7 bits per pixel"),
        (b"II*\x00" + struct.pack("<I", 1 << 31), "cut short: the file ends within its first IFD"),
        (b"II*\x00" + struct.pack("<IH", 8, 0) + bytes(4), "its first TIFF IFD has no ImageWidth or ImageLength"),
        (b"II+\x00" + struct.pack("<HH", 4, 0) + bytes(8), "its BigTIFF header gives an offset size other than 8"),
        (b"\xff\xd8\xff\xda\x00\x08" + bytes(20), "its JPEG data come before a frame header (SOF)"),
        (b"\xff\xd8\xff\xe0\x00\x04\x00\x00\x12\x34", "no JPEG marker at byte 8"),
        (
            b"\xff\xd8\xff\xc0\x00\x11\x08\x00\x00\x00\x10\x01",
            "its JPEG frame header leaves the height to a DNL segment",
        ),
    ],
)
def test_garbage_and_damaged_headers_are_refused_naming_the_file(tmp_path: Path, data: bytes, reason: str) -> None:
    path = tmp_path / "frame_3.png"
    path.write_bytes(data)
    with pytest.raises(FramesError, match=re.escape(f"{path}: not an image slrig can read ({reason}")):
        read_image_header(path)
    with pytest.raises(FramesError, match=re.escape(f"upload 7: not an image slrig can read ({reason}")):
        image_header_bytes(data, "upload 7")


def test_damaged_headers_raise_only_frames_errors(tmp_path: Path) -> None:
    """Random bytes written over the first 64 of each format's file: a header, or FramesError."""
    rng = np.random.default_rng(5)
    for suffix in (".png", ".tif", ".bmp", ".jpg"):
        assert cv2.imwrite(str(tmp_path / f"x{suffix}"), _image((30, 20), np.uint8, 3))
        data = bytearray((tmp_path / f"x{suffix}").read_bytes())
        for _ in range(300):
            damaged = data.copy()
            for at in rng.integers(2 if suffix != ".tif" else 4, 64, rng.integers(1, 4)):
                damaged[at] = rng.integers(0, 256)
            try:
                image_header_bytes(bytes(damaged), "damaged")
            except FramesError as exc:
                assert str(exc).startswith("damaged: not an image slrig can read (")


def test_unreadable_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(FramesError, match=re.escape(f"{tmp_path}: cannot be read (")):
        read_image_header(tmp_path)


def test_check_image_size_names_the_file_its_size_and_the_limit() -> None:
    header = ImageHeader(20000, 20000, 1, 16, "PNG")
    check_image_size(header, "frame a.png", (20000, 20000), 400_000_000)
    check_image_size(header, "frame a.png", None, 400_000_000)
    with pytest.raises(
        FramesError,
        match=re.escape("frame a.png: 20000x20000 pixels (400.0 megapixels), more than the limit of 64000000 (64.0"),
    ):
        check_image_size(header, "frame a.png", None, 64_000_000)
    with pytest.raises(FramesError, match=re.escape("frame a.png: 20000x20000 pixels, expected 640x480")):
        check_image_size(header, "frame a.png", (640, 480), 400_000_000)


def _tiff_of(entries: list[tuple[int, int, int]]) -> bytes:
    """A little-endian TIFF whose first IFD holds these (tag, type, value) entries, one value each."""
    ifd = struct.pack("<H", len(entries)) + b"".join(struct.pack("<HHII", t, k, 1, v) for t, k, v in entries)
    return b"II*\0" + struct.pack("<I", 8) + ifd + b"\0\0\0\0"


@pytest.mark.parametrize(
    ("entries", "reason"),
    [
        ([(256, 4, 20000), (257, 4, 20000), (256, 3, 10), (257, 3, 10)], "tag 256 twice"),  # libtiff reads the first
        ([(256, 5, 10), (257, 4, 10)], "type 5"),  # a RATIONAL width: read otherwise by a decoder
        ([(256, 3, 10), (257, 3, 10)] + [(300 + k, 3, 0) for k in range(300)], "entries"),
    ],
)
def test_a_tiff_cannot_hide_its_size(entries: list[tuple[int, int, int]], reason: str) -> None:
    with pytest.raises(FramesError, match=reason):
        image_header_bytes(_tiff_of(entries), "hidden.tif")
    assert image_header_bytes(_tiff_of([(256, 4, 20000), (257, 3, 10)]), "plain.tif").size == (20000, 10)
