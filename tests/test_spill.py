"""Light spilled from a far brighter neighbour (rig.patterns.spill): a camera that sees the patterns
through a blurring lens over a black-and-white checker reads the dark side of each edge toward the
bright one; with `scan.exposure.drop_outshone` those pixels are left out, batch and stream alike."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rig.config import config_from_dict
from rig.patterns import codec_class
from rig.patterns.base import Codec
from rig.patterns.correspondence import Correspondence
from rig.patterns.spill import outshone
from rig.patterns.stream import decode_streamed
from rig.pipeline.scan import make_codec
from tests.conftest import UNCLIPPED_FULL_SCALE, small_config_data

WIDTH, HEIGHT, SQUARE = 320, 96, 32


def _seen_through_a_lens(codec: Codec, albedo: np.ndarray, blur_px: float = 0.8) -> list[np.ndarray]:
    """Each pattern, as the camera sees it lying on `albedo` (camera pixel = projector pixel), blurred
    by the lens, on 16-bit counts with headroom."""
    scale = 0.9 * UNCLIPPED_FULL_SCALE / 255.0
    frames = []
    for pattern in codec.patterns():
        light = cv2.GaussianBlur(pattern.astype(np.float32) * albedo * np.float32(scale), (0, 0), blur_px)
        frames.append(np.rint(light).astype(np.uint16))
    return frames


def _checker(dark: float) -> np.ndarray:
    rows, cols = np.indices((HEIGHT, WIDTH))
    return np.where((rows // SQUARE + cols // SQUARE) % 2 == 0, 1.0, dark).astype(np.float32)


def _phase(drops: bool) -> Codec:
    codec = codec_class("phase")((WIDTH, HEIGHT))
    codec.drops_outshone = drops
    return codec


def _column_error(corr: Correspondence) -> np.ndarray:
    return np.abs(corr.u - np.arange(WIDTH)[None, :])


def test_the_dark_side_of_an_edge_reads_toward_the_bright_side_and_is_left_out() -> None:
    albedo = _checker(0.06)  # 1:16, the dark side still lit enough to read
    frames = _seen_through_a_lens(_phase(False), albedo)
    kept = _phase(False).decode(frames, UNCLIPPED_FULL_SCALE)
    screened = _phase(True).decode(frames, UNCLIPPED_FULL_SCALE)
    dark = albedo < 0.5
    dark[:, :4] = dark[:, -4:] = False  # the frame's sides, where the lens's blur is mirrored, apart
    inner = cv2.erode(dark.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)  # 4 px from any edge
    error = _column_error(kept)
    assert kept.valid[dark].mean() > 0.95  # read everywhere, ...
    at_edges = dark & ~inner & kept.valid
    assert np.nanmax(error[at_edges]) > 10 * np.nanmax(error[inner & kept.valid])  # ... but wrong at the edges
    assert screened.counts["rejected_outshone"] > 0
    assert screened.counts["rejected_outshone"] == int((kept.valid & ~screened.valid).sum())
    good = screened.valid & dark
    assert np.nanmax(_column_error(screened)[good]) < 0.5 * np.nanmax(error[at_edges])
    assert screened.valid[inner].all()  # no pixel away from an edge is lost
    assert screened.valid[albedo > 0.5].mean() > 0.9  # nor is the bright side's plateau


@pytest.mark.parametrize("clipped_at", [None, 0.9])
def test_at_a_fifty_to_one_edge_only_the_pixels_mostly_lit_by_spill_are_left_out(clipped_at: float | None) -> None:
    """Across a 50:1 edge seen through a 0.6 px blur the dark side's first pixel takes 89 % of its
    light from the bright side and is left out; the next takes 11 % and is kept (the box's HDR
    read it so, beside a neighbour clipped in the long exposure)."""
    albedo = np.where(np.arange(40) < 20, 1.0, 0.02).astype(np.float32)[None].repeat(9, axis=0)
    white = cv2.GaussianBlur(albedo, (0, 0), 0.6)
    spilled = 1.0 - albedo / white  # the share of each pixel's light that is not its own
    if clipped_at is not None:
        white = np.minimum(white, np.float32(clipped_at))
    left_out = outshone(white, np.zeros_like(white))[4]
    np.testing.assert_allclose(spilled[4, 20:22], [0.89, 0.11], atol=0.01)
    assert left_out[20] and not left_out[21:].any()  # the first dark pixel only
    assert not left_out[:20].any()  # and none of the bright side


def test_a_uniform_surface_loses_no_pixel() -> None:
    frames = _seen_through_a_lens(_phase(True), np.full((HEIGHT, WIDTH), 0.5, np.float32))
    assert _phase(True).decode(frames, UNCLIPPED_FULL_SCALE).counts["rejected_outshone"] == 0


@pytest.mark.parametrize("name", ["phase", "gray"])
def test_stream_and_batch_leave_out_the_same_pixels(name: str) -> None:
    codec = codec_class(name)((WIDTH, HEIGHT))
    codec.drops_outshone = True
    frames = _seen_through_a_lens(codec, _checker(0.03))
    batch = codec.decode(frames, UNCLIPPED_FULL_SCALE)
    streamed = decode_streamed(codec, frames, UNCLIPPED_FULL_SCALE)
    assert batch.counts["rejected_outshone"] == streamed.counts["rejected_outshone"] > 0
    np.testing.assert_array_equal(batch.valid, streamed.valid)


def test_the_scan_config_sets_the_screen_and_it_is_off_by_default() -> None:
    from rig.assembly import open_rig

    data = small_config_data()
    with open_rig(config_from_dict(data, "default")) as rig:
        assert not make_codec(rig, 0).drops_outshone
    data["scan"]["exposure"] = {"drop_outshone": True}
    with open_rig(config_from_dict(data, "spill")) as rig:
        assert make_codec(rig, 0).drops_outshone
