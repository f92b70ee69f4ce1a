"""The camera's blur undone before decoding (rig.patterns.deblur, `scan.exposure.deblur_px`): beside
a far brighter neighbour a pixel reads its own pattern again and keeps its point; away from such
edges the frames are decoded as captured; batch and stream alike; on the bench, a dark-and-white
object scanned in one exposure."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rig.config import config_from_dict
from rig.patterns import codec_class
from rig.patterns.deblur import Deblur
from rig.patterns.stream import decode_streamed
from tests.conftest import UNCLIPPED_FULL_SCALE, small_config_data
from tests.test_spill import WIDTH, _checker, _column_error, _seen_through_a_lens

BLUR_PX = 0.6  # the simulated cameras'


def _phase(deblur_px: float) -> object:
    codec = codec_class("phase")((WIDTH, 96))
    codec.deblur_px = deblur_px
    return codec


def test_the_dark_side_of_an_edge_reads_its_own_pattern_again() -> None:
    albedo = _checker(0.1)  # 1:10, the dark side well above the codec's least contrast
    frames = _seen_through_a_lens(_phase(0.0), albedo, BLUR_PX)
    as_captured = _phase(0.0).decode(frames, UNCLIPPED_FULL_SCALE)
    restored = _phase(BLUR_PX).decode(frames, UNCLIPPED_FULL_SCALE)
    dark = albedo < 0.5
    dark[:, :4] = dark[:, -4:] = False  # the frame's sides, where the lens's blur is mirrored, apart
    inner = cv2.erode(dark.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    at_edges = dark & ~inner
    before, after = _column_error(as_captured)[at_edges], _column_error(restored)[at_edges]
    assert restored.valid[at_edges].mean() > 0.95  # kept, not left out
    assert np.nanmean(after) < 0.25 * np.nanmean(before)  # measured 0.007 against 0.040 px
    assert np.nanmax(after) < 0.6 * np.nanmax(before)  # 0.34 against 0.62 px
    np.testing.assert_array_equal(restored.u[inner], as_captured.u[inner])  # far from edges: as captured


def test_a_frame_without_strong_edges_is_left_as_captured_and_a_clipped_pixels_reach_is_clipped() -> None:
    smooth = (np.linspace(1000, 30000, 320, dtype=np.float32)[None, :] * np.ones((96, 1), np.float32)).astype(np.uint16)
    deblur = Deblur(BLUR_PX, 65535)
    assert deblur.restored(smooth) is smooth
    edge = np.full((32, 32), 600, np.uint16)
    edge[:, 16:] = 65535  # a bright side clipped
    restored = Deblur(BLUR_PX, 65535).restored(edge)
    assert (restored[:, 14:] == 65535).all() and (restored[:, :14] < 65535).all()  # its reach: 2 px


@pytest.mark.parametrize("name", ["phase", "gray"])
def test_stream_and_batch_restore_alike(name: str) -> None:
    codec = codec_class(name)((WIDTH, 96))
    codec.deblur_px = BLUR_PX
    frames = _seen_through_a_lens(codec, _checker(0.03), BLUR_PX)
    batch = codec.decode(frames, UNCLIPPED_FULL_SCALE)
    streamed = decode_streamed(codec, frames, UNCLIPPED_FULL_SCALE)
    np.testing.assert_array_equal(batch.valid, streamed.valid)
    np.testing.assert_allclose(batch.u[batch.valid], streamed.u[streamed.valid], atol=1e-4)  # sums in another order


def test_a_dark_and_white_box_in_one_exposure_is_measured_better() -> None:
    from rig.assembly import open_rig
    from rig.evaluate.pairs import evaluate_on_bench
    from rig.pipeline.hdr import scan_with_exposure

    rms = {}
    for blur in (0.0, 0.6):  # the small bench's camera blurs by 0.6 px
        data = small_config_data()
        data["simulation"]["scene"] = {"kind": "box"}
        data["simulation"]["texture"] = {"kind": "checker", "size_mm": 25.0, "colours": [[0.02] * 3, [1.0] * 3]}
        data["scan"]["exposure"] = {"exposure": "auto", "deblur_px": blur}
        with open_rig(config_from_dict(data, "deblur")) as rig:
            rms[blur] = evaluate_on_bench(rig, scan_with_exposure(rig).pairs[0])["rms_mm"]
    assert rms[0.6] < 0.6 * rms[0.0]  # measured 0.18 against 0.39 mm
