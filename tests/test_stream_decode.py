"""Decoding while capturing (rig.patterns.stream): every codec's stream gives what its batch
decoder (the reference) gives for the same frames."""

from __future__ import annotations

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.config import config_from_dict
from rig.errors import DecodeError
from rig.patterns import Codec, Correspondence, codec_class, codec_names
from rig.patterns.graycode import read_bits
from rig.patterns.stream import GrayBits, decode_streamed
from rig.pipeline.scan import capture, make_codec
from rig.progress import ProgressTracker
from tests.conftest import small_config_data

# The phase streams (and radial's finest level) sum their steps in another order than the batch
# decoder (OpenCV's fused multiply-add) and take a polynomial atan2: coordinates differ by float
# rounding, far below the decoder's noise.
PHASE_TOLERANCE_PX = 1e-3
# radial's float32 angle (radians) and radius (pixels) beside its coordinates, likewise where decoded
# (and a float32 rounding of the radius)
EXTRA_TOLERANCE = 1e-5


def _tolerance(name: str) -> float:
    """Phase codecs sum in another order in their streams: within float rounding, not bit for bit."""
    return PHASE_TOLERANCE_PX if name in ("phase", "cued_phase", "radial") else 0.0


def _captured(codec_name: str, **scan: object) -> tuple[Codec, list[np.ndarray]]:
    data = small_config_data()
    data["scan"]["codec"] = codec_name
    for key, value in scan.items():
        data["scan"].setdefault(codec_name, {})[key] = value
    config = config_from_dict(data, "stream-test")
    with open_rig(config) as rig:
        codec = make_codec(rig, 0)
        return codec, capture(rig, [codec], ProgressTracker(None))[(0, 0)]


def _assert_same(reference: Correspondence, streamed: Correspondence, tolerance_px: float = 0.0) -> None:
    assert reference.counts == streamed.counts
    np.testing.assert_array_equal(reference.valid, streamed.valid)
    assert streamed.texture is reference.texture or np.array_equal(streamed.texture, reference.texture)
    for axis in ("u", "v"):
        expected, got = getattr(reference, axis), getattr(streamed, axis)
        assert (expected is None) == (got is None), axis
        if expected is None:
            continue
        assert got.dtype == expected.dtype
        np.testing.assert_array_equal(np.isnan(expected), np.isnan(got))
        if tolerance_px == 0.0:
            np.testing.assert_array_equal(expected, got)
        else:
            assert float(np.nanmax(np.abs(expected - got))) <= tolerance_px
    # where not decoded, rounding may move a noise pixel's radius across a level's reach (radial)
    judged = reference.valid if tolerance_px else np.ones_like(reference.valid)
    np.testing.assert_allclose(streamed.quality[judged], reference.quality[judged], rtol=1e-5, atol=1e-6)
    assert reference.extra.keys() == streamed.extra.keys()
    for name, expected in reference.extra.items():
        if tolerance_px == 0.0:
            np.testing.assert_array_equal(streamed.extra[name], expected, err_msg=name)
        else:  # where not decoded the angle is the noise's: rounding may move it anywhere
            got, expected = streamed.extra[name][reference.valid], expected[reference.valid]
            np.testing.assert_allclose(got, expected, rtol=1e-6, atol=EXTRA_TOLERANCE, err_msg=name)
    assert (reference.samples is None) == (streamed.samples is None)
    if reference.samples is not None:
        assert streamed.samples is not None
        for name in ("camera_xy", "ring", "theta", "contrast", "fine_phase", "fine_periods"):
            expected, got = getattr(reference.samples, name), getattr(streamed.samples, name)
            assert (expected is None) == (got is None), name
            if expected is not None:
                np.testing.assert_array_equal(got, expected, err_msg=name)


@pytest.mark.parametrize("name", codec_names())
def test_every_codec_streams_what_its_batch_decoder_decodes(name: str) -> None:
    codec, frames = _captured(name)
    reference = codec.decode(frames, 255)
    assert reference.counts.get("decoded", 1) > 0
    _assert_same(reference, decode_streamed(codec, frames, 255), _tolerance(name))


@pytest.mark.parametrize("name", ["gray", "phase"])
def test_both_directions_stream_like_the_batch(name: str) -> None:
    codec, frames = _captured(name, directions="both")
    _assert_same(codec.decode(frames, 255), decode_streamed(codec, frames, 255), _tolerance(name))


@pytest.mark.parametrize("name", ["gray", "phase", "rings", "radial"])
def test_noise_frames_stream_like_the_batch(name: str) -> None:
    """Random frames put pixels at every threshold and every tie of a pattern with its inverse."""
    cls = codec_class(name)
    codec = cls((64, 48), cls.Params(rings=4) if name == "rings" else None)  # type: ignore[call-arg]
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (40, 50), dtype=np.uint8) for _ in range(codec.frame_count)]
    reference = codec.decode(frames, 255)
    decoded = reference.counts["ring_samples"] if name == "rings" else reference.counts["decoded"]
    assert 0 < decoded < 40 * 50
    _assert_same(reference, decode_streamed(codec, frames, 255), _tolerance(name))


@pytest.mark.parametrize(
    "scan", [{"tangential_period_px": None}, {"angle_steps": 3, "tangential_steps": 5}, {"rings": 12}]
)
def test_rings_without_the_fine_code_or_with_other_rings_stream_like_the_batch(scan: dict[str, object]) -> None:
    codec, frames = _captured("rings", **scan)
    reference = codec.decode(frames, 255)
    assert reference.counts["ring_samples"] > 1000
    _assert_same(reference, decode_streamed(codec, frames, 255))


@pytest.mark.parametrize("name", ["gray", "phase", "rings", "radial"])
def test_sixteen_bit_and_colour_frames_stream_like_the_batch(name: str) -> None:
    codec, frames = _captured(name)
    deep = [(frame.astype(np.uint16) * 16 + 7) for frame in frames]  # 12-bit counts
    tolerance = _tolerance(name)
    _assert_same(codec.decode(deep, 4095), decode_streamed(codec, deep, 4095), tolerance)
    colour = [np.dstack([frame, frame // 2, frame]) for frame in frames]
    _assert_same(codec.decode(colour, 255), decode_streamed(codec, colour, 255), tolerance)


def test_gray_bits_read_what_read_bits_reads() -> None:
    rng = np.random.default_rng(5)
    for bits in (1, 7, 8, 9, 12):
        pairs = [
            (rng.integers(0, 256, (9, 11), np.uint8), rng.integers(0, 256, (9, 11), np.uint8)) for _ in range(bits)
        ]
        value, strength = read_bits((p.astype(np.int32) - i for p, i in pairs), gray=True)
        by_pairs, by_frames = GrayBits(bits), GrayBits(bits)
        for pattern, inverse in pairs:
            by_pairs.add(pattern, inverse)
            by_frames.take(pattern)
            by_frames.take(inverse)
        for reader in (by_pairs, by_frames):
            np.testing.assert_array_equal(reader.value(), value)
            np.testing.assert_array_equal(np.minimum(reader.strength(), 255), np.minimum(strength, 255))


def test_a_stream_refuses_other_sizes_and_counts() -> None:
    codec = codec_class("gray")((64, 48))
    frame = np.zeros((40, 50), np.uint8)
    stream = codec.stream(255)
    stream.add(frame)
    with pytest.raises(DecodeError, match="differ in size"):
        stream.add(np.zeros((41, 50), np.uint8))
    with pytest.raises(DecodeError, match="differ in type"):
        stream.add(np.zeros((40, 50), np.uint16))
    with pytest.raises(DecodeError, match=f"expected {codec.frame_count} frames, got 1"):
        stream.finish()
    for _ in range(codec.frame_count - 1):
        stream.add(frame)
    with pytest.raises(DecodeError, match="got more"):
        stream.add(frame)
    with pytest.raises(DecodeError, match="8- or 16-bit"):
        codec.stream(255).add(frame.astype(np.float32))


def test_the_phase_streams_atan2_is_within_float_rounding_of_atan2() -> None:
    """rig.kernels.phase.atan2 (a polynomial, so that the phase loop vectorises) against atan2 in
    float64, over every direction and the axes, where float32 itself rounds by up to 2.4e-7 rad."""
    from rig.kernels.phase import atan2

    angles = np.linspace(-np.pi, np.pi, 200_001)
    radii = np.geomspace(1e-6, 1e3, angles.size)
    ys, xs = (radii * np.sin(angles)).astype(np.float32), (radii * np.cos(angles)).astype(np.float32)
    axes = np.array([[0, 1], [1, 0], [0, -1], [-1, 0], [0, 0], [2, 2], [-3, -3]], np.float32)
    ys, xs = np.concatenate([ys, axes[:, 0]]), np.concatenate([xs, axes[:, 1]])
    got = np.array([atan2(y, x) for y, x in zip(ys, xs, strict=True)], np.float64)
    error = np.abs(got - np.arctan2(ys.astype(np.float64), xs.astype(np.float64)))
    error = np.minimum(error, 2 * np.pi - error)  # -pi and pi are the same direction
    assert float(error.max()) < 3.5e-7
