"""Folders of frames other systems captured: read in order at their bit depth, and refused, naming
the file, where they do not hold what the description lists."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from rig.errors import FramesError, PatternSpecError
from rig.patterns.described import decode_described, described_patterns
from rig.patterns.spec import FrameFiles, GrayCode, PatternSpec, ProjectorSpace
from rig.store.frames import load_pattern_spec, open_frames, read_frames

SPEC_YAML = """
projector: {resolution: [64, 32]}
frames: {files: "frame_*.png"}
gray: {axes: [columns, rows], white_black: last}
"""


def _folder(tmp_path: Path, spec: PatternSpec, depth: type = np.uint8, colour: bool = False) -> Path:
    folder = tmp_path / "frames"
    folder.mkdir()
    scale = 257 if depth == np.uint16 else 1
    for i, pattern in enumerate(described_patterns(spec)):
        image = (20 + 0.7 * pattern.astype(np.float64)) * scale
        image = np.dstack([image * 0.9, image, image * 1.1]) if colour else image
        cv2.imwrite(str(folder / f"frame_{i}.png"), np.clip(image, 0, 255 * scale).astype(depth))
    return folder


@pytest.mark.parametrize(("depth", "colour"), [(np.uint8, False), (np.uint16, False), (np.uint8, True)])
def test_a_folder_of_frames_decodes_in_number_order(tmp_path: Path, depth: type, colour: bool) -> None:
    path = tmp_path / "spec.yaml"
    path.write_text(SPEC_YAML)
    spec = load_pattern_spec(path)
    folder = _folder(tmp_path, spec, depth, colour)
    frames = read_frames(folder, spec.frames, len(spec.roles()))
    assert [p.name for p in frames.files][:3] == ["frame_0.png", "frame_1.png", "frame_2.png"]  # frame_10 later
    assert frames.full_scale == (65535 if depth == np.uint16 else 255) and frames.frames[0].ndim == 2
    assert len(frames.sha256) == len(spec.roles())
    found = decode_described(frames.frames, spec, frames.full_scale)
    assert found.u is not None and found.valid.all()
    assert np.array_equal(found.u[0], np.arange(64))


def test_a_folder_that_does_not_hold_the_description_is_refused_naming_the_file(tmp_path: Path) -> None:
    spec = PatternSpec(
        projector=ProjectorSpace(resolution=(64, 32)), frames=FrameFiles(files="frame_*.png"), gray=GrayCode()
    )
    folder = _folder(tmp_path, spec)
    count = len(spec.roles())
    cv2.imwrite(str(folder / f"frame_{count}.png"), np.zeros((32, 64), np.uint8))
    with pytest.raises(
        FramesError,
        match=re.escape(f"has {count} frames, {count + 1} files match 'frame_*.png' (beyond them: frame_{count}.png"),
    ):
        read_frames(folder, spec.frames, count)
    (folder / f"frame_{count}.png").unlink()
    (folder / "frame_3.png").unlink()
    with pytest.raises(FramesError, match=f"has {count} frames, {count - 1} files"):
        read_frames(folder, spec.frames, count)
    listed = FrameFiles(files=[f"frame_{i}.png" for i in range(count)])
    with pytest.raises(FramesError, match=re.escape("missing frame_3.png")):
        read_frames(folder, listed, count)
    (folder / "frame_3.png").write_bytes(b"not a png")
    with pytest.raises(FramesError, match=re.escape("frame_3.png: not an image")):
        read_frames(folder, spec.frames, count)
    cv2.imwrite(str(folder / "frame_3.png"), np.zeros((16, 64), np.uint8))
    with pytest.raises(
        FramesError, match=re.escape("frame_3.png: 64x16 8-bit, the first frame (frame_0.png) is 64x32 8-bit")
    ):
        read_frames(folder, spec.frames, count)
    with pytest.raises(FramesError, match="not a folder"):
        read_frames(tmp_path / "nowhere", spec.frames, count)


def test_a_description_that_does_not_hold_names_its_field(tmp_path: Path) -> None:
    path = tmp_path / "spec.yaml"
    path.write_text("projector: {resolution: [64, 32]}\ngray: {order: middle_first, bits: 3}\n")
    with pytest.raises(
        PatternSpecError, match=re.escape("gray.order: Input should be 'msb_first' or 'lsb_first'")
    ) as caught:
        load_pattern_spec(path)
    assert [p.split(":")[0] for p in caught.value.problems] == ["gray.order"]
    path.write_text("projector: {resolution: [64, 32]}\ngray: {bits: 3}\n")
    with pytest.raises(PatternSpecError, match=re.escape("gray.bits 3: too few for 64 columns")):
        load_pattern_spec(path)
    path.write_text("projector: [")
    with pytest.raises(PatternSpecError, match="cannot be read"):
        load_pattern_spec(path)


def test_a_list_of_names_and_globs_gives_each_frequency_its_own_files(tmp_path: Path) -> None:
    """Per-frequency frame lists: a system that names each frequency's frames its own way."""
    spec = PatternSpec.model_validate(
        {
            "projector": {"resolution": [64, 32]},
            "frames": {"files": ["white.png", "black.png", "coarse_*.png", "fine_*.png"]},
            "phase": {
                "frequencies": [{"period_px": 64, "steps": 4}, {"period_px": 8, "steps": 4}],
                "unwrap": "hierarchical",
                "white_black": "first",
            },
        }
    )
    folder = tmp_path / "frames"
    folder.mkdir()
    names = ["white.png", "black.png", *(f"coarse_{n}.png" for n in range(4)), *(f"fine_{n}.png" for n in range(4))]
    for name, pattern in zip(names, described_patterns(spec), strict=True):
        cv2.imwrite(str(folder / name), (20 + 0.7 * pattern.astype(np.float64)).astype(np.uint8))
    frames = read_frames(folder, spec.frames, len(spec.roles()))
    assert [p.name for p in frames.files] == names
    found = decode_described(frames.frames, spec, frames.full_scale)
    assert found.u is not None and found.valid.all()
    assert np.abs(found.u[0] - np.arange(64)).max() < 0.05
    (folder / "fine_3.png").unlink()
    with pytest.raises(FramesError, match="9 files are listed"):
        read_frames(folder, spec.frames, len(spec.roles()))
    for name in names[6:9]:
        (folder / name).unlink()
    with pytest.raises(FramesError, match=re.escape("missing fine_*.png (no file matches)")):
        read_frames(folder, spec.frames, len(spec.roles()))


@pytest.mark.parametrize("files", ["../*.png", "/etc/passwd", ["white.png", "../../x.png"], ".*", "C:frame.png"])
def test_a_description_cannot_name_files_outside_its_folder(files: object) -> None:
    with pytest.raises(ValueError, match="within the frames folder"):
        FrameFiles(files=files)  # type: ignore[arg-type]


def test_frames_opened_as_they_arrive_decode_as_frames_read_first(tmp_path: Path) -> None:
    """open_frames (read on threads while the decoder walks them) gives the same correspondence and
    hashes as read_frames, and names a frame of another size when the decoder reaches it."""
    path = tmp_path / "spec.yaml"
    path.write_text(SPEC_YAML)
    spec = load_pattern_spec(path)
    folder = _folder(tmp_path, spec)
    eager = read_frames(folder, spec.frames, len(spec.roles()))
    arriving = open_frames(folder, spec.frames, len(spec.roles()))
    first, second = (decode_described(f.frames, spec, f.full_scale) for f in (eager, arriving))
    assert np.array_equal(first.valid, second.valid) and np.array_equal(first.u, second.u, equal_nan=True)
    assert arriving.sha256 == eager.sha256
    cv2.imwrite(str(folder / "frame_7.png"), np.zeros((16, 64), np.uint8))
    arriving = open_frames(folder, spec.frames, len(spec.roles()))
    with pytest.raises(FramesError, match=r"frame_7\.png: 64x16 8-bit, the first frame \(frame_0\.png\) is 64x32"):
        decode_described(arriving.frames, spec, arriving.full_scale)
