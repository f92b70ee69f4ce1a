"""Saturation is never a point (rig.patterns.saturation): a pixel at full scale in any frame it
decodes from is left out by every codec, batch and stream alike, and counted."""

from __future__ import annotations

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.config import config_from_dict
from rig.patterns import codec_names
from rig.patterns.saturation import SaturationMask
from rig.patterns.stream import decode_streamed
from rig.pipeline.scan import capture, make_codec
from rig.progress import ProgressTracker
from tests.conftest import small_config_data


@pytest.mark.parametrize("name", codec_names())
def test_a_pixel_clipped_in_one_frame_is_no_point_in_any_codec(name: str) -> None:
    data = small_config_data()
    data["scan"]["codec"] = name
    with open_rig(config_from_dict(data, "saturation")) as rig:
        codec = make_codec(rig, 0)
        frames = capture(rig, [codec], ProgressTracker(None))[(0, 0)]
    clean = codec.decode(frames, 255)
    assert clean.counts["rejected_saturated"] == 0  # the bench's grey surfaces stay below full scale
    assert decode_streamed(codec, frames, 255).counts == clean.counts  # counted, as none, by the stream too
    height, width = frames[0].shape[:2]
    block = (slice(height // 3, 2 * height // 3), slice(width // 3, 2 * width // 3))
    clipped = [f.copy() for f in frames]
    clipped[-1][block] = 255  # the last coded frame clips over the block, no other frame does
    for decoded in (codec.decode(clipped, 255), decode_streamed(codec, clipped, 255)):
        assert not decoded.valid[block].any()
        if clean.samples is None:
            assert clean.valid[block].any()
            # the pixels the block would have decoded (the clipped frame reads a few others than the clean one)
            count, was_valid = decoded.counts["rejected_saturated"], int(clean.valid[block].sum())
            assert 0.95 * was_valid <= count <= clean.valid[block].size
            for axis in (decoded.u, decoded.v):
                assert axis is None or np.isnan(axis[block]).all()
        else:
            assert decoded.samples is not None
            x, y = decoded.samples.camera_xy.T
            inside = (x > block[1].start - 1) & (x < block[1].stop) & (y > block[0].start - 1) & (y < block[0].stop)
            assert not inside.any()
            assert decoded.counts["rejected_saturated"] >= len(clean.samples) - len(decoded.samples) > 0
    assert codec.decode(clipped, 255).counts == decode_streamed(codec, clipped, 255).counts


@pytest.mark.parametrize(("shape", "full_scale"), [((6, 8), 4095), ((6, 8, 3), 255)])
def test_a_stream_knows_whether_any_pixel_clipped_without_making_its_mask(
    shape: tuple[int, ...], full_scale: int
) -> None:
    """A 12-bit frame, and a colour frame clipped in one channel of one pixel."""
    dtype = np.uint16 if full_scale > 255 else np.uint8
    saturation = SaturationMask(full_scale)
    assert not saturation.clipped and saturation.mask is None  # no frame yet
    saturation.add(np.full(shape, full_scale - 1, dtype))
    assert not saturation.clipped and not saturation.mask.any()
    frame = np.zeros(shape, dtype)
    frame[(2, 5, 1) if len(shape) == 3 else (2, 5)] = full_scale
    saturation.add(frame)
    assert saturation.clipped
    assert np.array_equal(np.argwhere(saturation.mask), [[2, 5]])
