"""cued_phase (rig.patterns.cued_phase): 3 fringe steps and 3 of a single-period cue, no white or
dark frame; accurate through a linear projector, refused (not wrong) through an uncorrected gamma."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.config import config_from_dict
from rig.errors import DecodeError
from rig.kernels import phase as phase_kernels
from rig.patterns import cued_phase
from rig.patterns.stream import decode_streamed
from rig.pipeline.live import run_live
from rig.pipeline.scan import capture, make_codec
from rig.progress import ProgressTracker
from tests.conftest import small_config_data


def _bench(gamma: float, steps: int) -> dict[str, Any]:
    data = small_config_data()
    data["projectors"][0]["sim"]["gamma"] = gamma  # 1: a DLP's 8-bit patterns, light linear in the level
    data["scan"]["codec"] = "cued_phase"
    data["scan"]["cued_phase"] = {"steps": steps, "period_px": 16}  # a cue 17 periods long, as by default
    return data


def _decoded_error(data: dict[str, Any]) -> tuple[np.ndarray, Any]:
    """|decoded - true| projector column at every decoded pixel, and the Correspondence."""
    with open_rig(config_from_dict(data, "cued")) as rig:
        codec = make_codec(rig, 0)
        frames = capture(rig, [codec], ProgressTracker(None))[(0, 0)]
        truth = rig.truth.ground_truth(0, 0)  # type: ignore[union-attr]
    corr = codec.decode(frames, 255)
    return np.abs(corr.u - truth.projector_uv[..., 0])[corr.valid], corr


def test_six_frames_without_a_white_or_dark_one_read_the_projector_column() -> None:
    data = _bench(1.0, 3)
    with open_rig(config_from_dict(data, "cued")) as rig:
        codec = make_codec(rig, 0)
        patterns = codec.patterns()
    assert codec.frame_count == len(patterns) == 6
    assert all(0 < p.mean() < 255 for p in patterns)  # fringes all: none is a white or a dark frame
    error, corr = _decoded_error(data)
    assert corr.valid.sum() > 0.97 * corr.counts["lit"]
    # px; measured 0.037, 0.27 and 0.006 %: the few far off are mixed pixels at the sphere's limb
    assert np.median(error) < 0.1 and np.percentile(error, 99) < 0.6 and (error > 5).mean() < 1e-3
    assert corr.texture is not None and corr.texture.dtype == np.uint8


def test_an_uncorrected_gamma_is_refused_with_three_steps_and_read_with_four() -> None:
    with open_rig(config_from_dict(_bench(2.2, 3), "cued")) as rig:  # what benches ask to pick a rig
        assert make_codec(rig, 0).needs_linear_light and not make_codec(rig, 0, "phase").needs_linear_light
    assert not cued_phase.CuedPhaseCodec((256, 192), cued_phase.CuedPhaseParams(steps=4)).needs_linear_light
    with pytest.raises(DecodeError, match=r"calibrate its response.*4 steps"):
        _decoded_error(_bench(2.2, 3))
    error, corr = _decoded_error(_bench(2.2, 4))  # 4 steps cancel the gamma's second harmonic
    assert corr.valid.sum() > 0.97 * corr.counts["lit"] and np.median(error) < 0.15


def test_live_mode_shows_the_six_frame_sequence() -> None:
    data = _bench(1.0, 3)
    data["scan"]["live"] = {"codec": "cued_phase"}
    frames: list[Any] = []
    asked = iter(range(2))
    with open_rig(config_from_dict(data, "cued live")) as rig:
        run_live(rig, frames.append, lambda: next(asked, None) is not None)
        truth = rig.truth.ground_truth(0, 0)  # type: ignore[union-attr]
    depth = frames[-1].depths[0]
    found = np.isfinite(depth)
    assert found.mean() > 0.7
    error = np.abs(depth[found] - truth.depth[found])
    # mm; measured 0.19 and 0.98: twice the period and half the steps of the 6-step phase live test
    # (0.08 and 0.66), as the noise predicts (2 x sqrt(2))
    assert np.median(error) < 0.3 and np.percentile(error, 99) < 2.0


def test_the_kernel_and_the_codec_number_a_pixels_status_alike() -> None:
    names = ("UNLIT", "DECODED", "CUE_OFF", "OUTSIDE", "LOW_MODULATION")
    assert [getattr(phase_kernels, n) for n in names] == [getattr(cued_phase, n) for n in names]
    assert cued_phase.SATURATED not in [getattr(phase_kernels, n) for n in names]


def test_colour_frames_with_the_spill_screen_decode_alike_in_batch_and_stream() -> None:
    """The fringes' peak and trough stand in for the white and dark frames the spill screen reads:
    it drops about what it drops for phase, which shows them (1010 pixels against 1039 measured)."""
    with open_rig(config_from_dict(_bench(1.0, 3), "cued")) as rig:
        codec, phase = make_codec(rig, 0), make_codec(rig, 0, "phase")
        frames = capture(rig, [codec], ProgressTracker(None))[(0, 0)]
        phase_frames = capture(rig, [phase], ProgressTracker(None))[(0, 0)]
    colour = [np.repeat(f[..., None], 3, axis=2) for f in frames]
    codec.drops_outshone = phase.drops_outshone = True
    batch, streamed = codec.decode(colour, 255), decode_streamed(codec, colour, 255)
    assert batch.texture is not None and batch.texture.shape == colour[0].shape
    # the screen's threshold meets modulations equal within float rounding: a pixel may fall either side
    assert (batch.valid != streamed.valid).sum() <= 1e-4 * batch.valid.size
    both = batch.valid & streamed.valid
    assert np.abs(batch.u[both] - streamed.u[both]).max() < 1e-3
    shown = phase.decode(phase_frames, 255).counts["rejected_outshone"]
    assert shown > 0 and abs(batch.counts["rejected_outshone"] - shown) < 0.1 * shown


def test_undoing_the_blur_is_refused_for_want_of_a_white_frame() -> None:
    with open_rig(config_from_dict(_bench(1.0, 3), "cued")) as rig:
        codec = make_codec(rig, 0)
        frames = capture(rig, [codec], ProgressTracker(None))[(0, 0)]
    codec.deblur_px = 0.6
    for decode in (codec.decode, lambda f, s: decode_streamed(codec, f, s)):
        with pytest.raises(DecodeError, match=r"deblur_px.*white frame"):
            decode(frames, 255)
