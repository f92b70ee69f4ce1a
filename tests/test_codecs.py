"""Codecs, noise-free: encode -> decode recovers projector coordinates."""

from __future__ import annotations

import tracemalloc

import cv2
import numpy as np
import pytest

from rig.errors import DecodeError, UnknownCodecError
from rig.patterns import codec_class, codec_names
from rig.patterns.gray import GrayParams
from rig.patterns.phase import PhaseParams
from tests.conftest import UNCLIPPED_FULL_SCALE, unclipped


def _grid(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    v, u = np.mgrid[0:height, 0:width]
    return u.astype(float), v.astype(float)


@pytest.mark.parametrize("size", [(1024, 768), (912, 1140), (100, 37)])
@pytest.mark.parametrize("directions", ["columns", "rows", "both"])
def test_gray_roundtrip_is_exact(size: tuple[int, int], directions: str) -> None:
    codec = codec_class("gray")(size, GrayParams(directions=directions))
    corr = codec.decode(unclipped(codec.patterns()), UNCLIPPED_FULL_SCALE)
    u, v = _grid(*size)
    assert corr.valid.all()
    if directions in ("columns", "both"):
        np.testing.assert_array_equal(corr.u, u)
    if directions in ("rows", "both"):
        np.testing.assert_array_equal(corr.v, v)
    if directions == "columns":
        assert corr.v is None
    if directions == "rows":
        assert corr.u is None


@pytest.mark.parametrize("size", [(1024, 768), (912, 1140)])
def test_phase_roundtrip_within_a_hundredth_pixel(size: tuple[int, int]) -> None:
    codec = codec_class("phase")(size, PhaseParams(directions="both"))  # default: 8 steps, 16 px
    corr = codec.decode(unclipped(codec.patterns()), UNCLIPPED_FULL_SCALE)
    u, v = _grid(*size)
    assert corr.valid.all()
    assert np.max(np.abs(corr.u - u)) <= 0.01
    assert np.max(np.abs(corr.v - v)) <= 0.01


@pytest.mark.parametrize(("steps", "period"), [(4, 32), (3, 12), (12, 64), (6, 8)])
def test_phase_roundtrip_other_steps_and_periods(steps: int, period: int) -> None:
    """8-bit patterns limit the phase to a few milliradians whatever N and P are."""
    codec = codec_class("phase")((912, 300), PhaseParams(steps=steps, period_px=period))
    corr = codec.decode(unclipped(codec.patterns()), UNCLIPPED_FULL_SCALE)
    assert corr.valid.all()
    phase_error = np.max(np.abs(corr.u - _grid(912, 300)[0])) * 2 * np.pi / period
    assert phase_error <= 0.005


def test_phase_unwrapping_does_not_break_at_period_edges() -> None:
    """A camera that sees the projector shifted by a fraction of a pixel and blurred puts the Gray
    edges and the phase wraps at slightly different places; no pixel may jump by a period."""
    size = (512, 64)
    codec = codec_class("phase")(size, PhaseParams(steps=8, period_px=16))
    for shift in (-0.45, -0.2, 0.13, 0.37, 0.5):
        map_x = (np.arange(size[0] - 2, dtype=np.float32) + 1 + shift)[None, :].repeat(size[1], 0)
        map_y = np.arange(size[1], dtype=np.float32)[:, None].repeat(size[0] - 2, 1)
        frames = []
        for pattern in codec.patterns():
            image = cv2.remap(pattern.astype(np.float32), map_x, map_y, cv2.INTER_LINEAR)
            frames.append(np.rint(cv2.GaussianBlur(image, (0, 0), 0.8)).astype(np.uint8))
        corr = codec.decode(unclipped(frames), UNCLIPPED_FULL_SCALE)
        inner = corr.valid.copy()
        inner[:, :3] = inner[:, -3:] = False  # the blur's image border is not the codec's concern
        error = corr.u[inner] - map_x[inner]
        assert corr.valid.mean() > 0.98
        assert np.max(np.abs(error)) < 0.25, f"shift {shift}: max error {np.max(np.abs(error))}"


def test_phase_sign_convention() -> None:
    """Pattern n is 0.5 + 0.5 cos(2 pi x / P - 2 pi n / N): check one column by hand."""
    codec = codec_class("phase")((64, 4), PhaseParams(steps=4, period_px=16))
    coded = codec.patterns()[2:6]
    x = 5
    expected = [0.5 + 0.5 * np.cos(2 * np.pi * x / 16 - 2 * np.pi * n / 4) for n in range(4)]
    np.testing.assert_allclose([p[0, x] / 255 for p in coded], expected, atol=0.5 / 255)


def test_phase_rejects_odd_period() -> None:
    with pytest.raises(ValueError, match="even"):
        codec_class("phase")((64, 64), PhaseParams(period_px=15))


def test_decode_masks_unlit_pixels() -> None:
    size = (128, 32)
    codec = codec_class("gray")(size)
    frames = [p.copy() for p in codec.patterns()]
    for f in frames:
        f[:, :40] = 3  # a shadow: the same dim value in every frame
    corr = codec.decode(unclipped(frames), UNCLIPPED_FULL_SCALE)
    assert not corr.valid[:, :40].any()
    assert corr.valid[:, 40:].all()
    assert np.isnan(corr.u[:, :40]).all()


def test_wrong_frame_count_is_a_decode_error() -> None:
    codec = codec_class("gray")((64, 64))
    with pytest.raises(DecodeError, match="expected"):
        codec.decode(unclipped(codec.patterns()[:-1]), UNCLIPPED_FULL_SCALE)


def test_unknown_codec_names_the_known_ones() -> None:
    with pytest.raises(UnknownCodecError, match="gray, phase"):
        codec_class("moire")
    assert {"gray", "phase"} <= set(codec_names())


def test_colour_frames_decode_like_mono() -> None:
    codec = codec_class("gray")((64, 16))
    frames = [cv2.cvtColor(p, cv2.COLOR_GRAY2BGR) for p in codec.patterns()]
    corr = codec.decode(unclipped(frames), UNCLIPPED_FULL_SCALE)
    np.testing.assert_array_equal(corr.u, _grid(64, 16)[0])
    assert corr.texture.ndim == 3


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("gray", {}),
        ("gray", {"directions": "both"}),
        ("phase", {}),
        ("phase", {"directions": "rows", "steps": 5, "period_px": 10}),
        ("rings", {}),
        ("rings", {"rings": 5, "angle_steps": 6}),
        ("radial", {}),
        ("radial", {"angle_periods": 64, "mid_periods": 8, "steps": 4}),
    ],
)
def test_frame_count_matches_the_patterns(name: str, params: dict) -> None:  # type: ignore[type-arg]
    cls = codec_class(name)
    codec = cls((320, 200), cls.Params(**params))
    patterns = codec.patterns()
    assert codec.frame_count == len(patterns)
    assert all(p.shape == (200, 320) and p.dtype == np.uint8 for p in patterns)


@pytest.mark.parametrize("name", ["gray", "phase"])
def test_line_codecs_make_each_pattern_only_when_it_is_asked_for(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A streaming capture shows patterns one by one; a line codec makes each image from its 1-D
    profile as its turn comes, so that the scan never holds the whole sequence."""
    lut = (255 - np.arange(256)).astype(np.uint8)  # a response that shows whether it was applied
    codec = codec_class(name)((320, 200), output_lut=lut)
    made: list[str] = []
    stretch = codec.stretch
    monkeypatch.setattr(codec, "stretch", lambda line, axis: made.append(axis) or stretch(line, axis))
    patterns = codec.iter_patterns()
    white, black, first = next(patterns), next(patterns), next(patterns)
    assert len(made) == 1
    rest = list(patterns)
    assert len(made) == codec.frame_count - 2 == len(rest) + 1
    assert white.min() == 255 and black.max() == 0  # the lit and dark frames are not the response's
    assert np.array_equal(first, lut[stretch(codec._coded_lines()[0][0], "u")])


@pytest.mark.parametrize("name", ["rings", "radial"])
def test_circular_codecs_make_each_pattern_only_when_it_is_asked_for(name: str) -> None:
    """The circular codecs' patterns are images of the projector's polar coordinates; made one by one
    as a streaming capture shows them, only those coordinates are held between them, not the
    sequence and its float temporaries (all at once, 75 MB of a ring scan's peak)."""
    codec = codec_class(name)((640, 480))
    tracemalloc.start()
    try:
        shown = sum(1 for _ in codec.iter_patterns())  # each dropped as the next is made, as a capture does
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert shown == codec.frame_count
    assert peak < 32 * 640 * 480  # four float64 images' bytes: the angle, the int32 zones and a pattern's making
