"""Decompression bombs in a frames folder: refused from their headers before anything is decoded,
in bounded time and memory."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

from rig.errors import FramesError
from rig.patterns.spec import FrameFiles
from rig.store import frames as frames_module
from rig.store.frames import MAX_FRAME_PIXELS, open_frames, read_frames
from rig.store.image_header import ImageHeader, read_image_header
from tests.bombs import write_png_bomb
from tests.conftest import REPO

BOMB_SIZE = 20000  # 20000 x 20000 at 16 bits: 800 MB of pixels in a 0.78 MB file


@pytest.fixture(scope="module")
def bomb(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 16-bit PNG of 20000 x 20000 zeros: 0.78 MB that decodes to 800 MB (written in 3 s)."""
    path = tmp_path_factory.mktemp("bomb") / "bomb.png"
    assert write_png_bomb(path, BOMB_SIZE, BOMB_SIZE) < 10**6
    return path


def test_the_bomb_is_a_valid_png(tmp_path: Path) -> None:
    """write_png_bomb's PNG decodes (small here) to what its header says, every pixel 0."""
    for width, height, bits in ((100, 70, 16), (33, 17, 1), (65, 3, 4), (300, 200, 8)):
        path = tmp_path / f"{bits}.png"
        assert write_png_bomb(path, width, height, bits) == path.stat().st_size
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        assert image.shape == (height, width) and not image.any()
        assert image.dtype == (np.uint16 if bits == 16 else np.uint8)
        header = read_image_header(path)
        assert (header.width, header.height, header.channels, header.bits_per_sample) == (width, height, 1, bits)


def _folder(tmp_path: Path, bomb: Path | None, at: set[int], count: int = 6) -> Path:
    """A folder of `count` 16-bit frames of 64 x 32, the ones at `at` the bomb (linked, not copied)."""
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(count):
        path = folder / f"frame_{i}.png"
        if i in at and bomb is not None:
            os.link(bomb, path)
        else:
            assert cv2.imwrite(str(path), np.full((32, 64), 1000 * i, np.uint16))
    return folder


FILES = FrameFiles(files="frame_*.png")


@pytest.fixture
def decoded(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The sizes in bytes of the files OpenCV decodes while the test runs."""
    for thread in threading.enumerate():  # an earlier test's readers, still reading frames it gave up on
        if thread.name.startswith("ThreadPoolExecutor"):
            thread.join(30)
    sizes: list[int] = []
    imdecode = cv2.imdecode

    def counted(buf: np.ndarray, flags: int) -> np.ndarray | None:
        sizes.append(len(buf))
        return imdecode(buf, flags)

    monkeypatch.setattr(frames_module.cv2, "imdecode", counted)
    return sizes


@pytest.mark.parametrize("at", [{0}, {3}, {1, 2, 3, 4, 5}])
def test_a_frames_folder_with_a_bomb_is_refused_without_decoding_it(
    tmp_path: Path, bomb: Path, decoded: list[int], at: set[int]
) -> None:
    folder = _folder(tmp_path, bomb, at)
    refusal = re.escape(
        f"frame {folder}/frame_{min(at)}.png: 20000x20000 pixels (400.0 megapixels), "
        f"more than the limit of {MAX_FRAME_PIXELS}"
    )
    with pytest.raises(FramesError, match=refusal):
        read_frames(folder, FILES, 6)
    assert decoded == []  # every header checked before any frame is decoded
    with pytest.raises(FramesError, match=refusal):  # the first at once, the others when reached
        list(open_frames(folder, FILES, 6).frames)
    assert bomb.stat().st_size not in decoded


def test_a_bomb_over_the_limit_alone_is_refused_for_its_size(tmp_path: Path, bomb: Path, decoded: list[int]) -> None:
    """A folder of one frame: nothing to compare it with, the limit refuses it."""
    folder = tmp_path / "one"
    folder.mkdir()
    os.link(bomb, folder / "frame_0.png")
    for read in (read_frames, open_frames):
        with pytest.raises(FramesError, match=re.escape(f"more than the limit of {MAX_FRAME_PIXELS}")):
            read(folder, FILES, 1)
    assert decoded == []


def test_frames_of_another_size_than_the_camera_are_refused_before_decoding(tmp_path: Path, decoded: list[int]) -> None:
    folder = _folder(tmp_path, None, set())
    assert len(read_frames(folder, FILES, 6, resolution=(64, 32)).frames) == 6
    assert len(open_frames(folder, FILES, 6, resolution=(64, 32)).frames[:]) == 6
    decoded.clear()
    for read in (read_frames, open_frames):
        with pytest.raises(FramesError, match=re.escape("frame_0.png: 64x32 pixels, expected 640x480")):
            read(folder, FILES, 6, resolution=(640, 480))
    assert decoded == []


def test_a_frame_replaced_after_its_header_was_read_is_checked_again(
    tmp_path: Path, bomb: Path, decoded: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The bytes decoded are the bytes checked: a frame swapped for the bomb between the header
    pass and the reading is refused, not decoded."""
    folder = _folder(tmp_path, None, set())
    header = frames_module._header

    def swapped(path: Path, data: bytes | None = None) -> ImageHeader:
        if data is None and path.name == "frame_5.png":
            found = header(path)
            path.unlink()
            os.link(bomb, path)
            return found
        return header(path, data)

    monkeypatch.setattr(frames_module, "_header", swapped)
    with pytest.raises(FramesError, match=re.escape("frame_5.png: 20000x20000 pixels")):
        read_frames(folder, FILES, 6)
    assert bomb.stat().st_size not in decoded


MEASURE = """
import json, resource, sys, time
from pathlib import Path
from rig.errors import FramesError
from rig.patterns.spec import FrameFiles
from rig.store.frames import open_frames, read_frames

before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
started = time.perf_counter()
refused = []
for folder in sys.argv[1:]:
    for read in (read_frames, open_frames):
        try:
            list(read(Path(folder), FrameFiles(files="frame_*.png"), 34).frames)
        except FramesError as exc:
            refused.append(str(exc))
seconds = time.perf_counter() - started
growth = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
print(json.dumps({"refused": refused, "growth_mb": growth, "seconds": seconds}))
"""


@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss in KiB, as Linux gives it")
def test_34_bombs_cost_neither_time_nor_memory(tmp_path: Path, bomb: Path) -> None:
    """The issue's reconstruction: the bomb as each of 34 frames (or all but the first), read in
    a fresh process whose peak memory may grow by far less than one decoded bomb (800 MB)."""
    folders = []
    for name, at in (("all", set(range(34))), ("after_first", set(range(1, 34)))):
        (tmp_path / name).mkdir()
        folders.append(str(_folder(tmp_path / name, bomb, at, 34)))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    done = subprocess.run(
        [sys.executable, "-c", MEASURE, *folders], capture_output=True, text=True, env=env, timeout=120, check=True
    )
    measured = json.loads(done.stdout)
    assert len(measured["refused"]) == 4, measured
    assert all("frame_0.png: 20000x20000 pixels (400.0 megapixels)" in m for m in measured["refused"][:2])
    assert all("frame_1.png: 20000x20000 pixels (400.0 megapixels)" in m for m in measured["refused"][2:])
    assert measured["growth_mb"] < 200 and measured["seconds"] < 5, measured
