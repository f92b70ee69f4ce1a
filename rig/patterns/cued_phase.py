"""`cued_phase`: N-step phase shift at the fringe period, unwrapped by N steps of a single period
that spans the projector (a cue), and nothing else: 2N frames, 6 at N = 3, with no white or dark
frame (the fringes give the lit mask and the texture themselves). The shortest sequence slrig
shows, for live mode at a camera's full rate (SLStudio's "phase shift 2 x 3" is the same idea).

Pattern n of a period Q, for projector coordinate x (pixel centres at integers), is
    0.5 + 0.5 cos(2 pi x / Q - 2 pi n / N),
first at Q = P (the fine fringes), then at Q = C = extent + P (the cue; one period more than the
projector, so that its phase does not wrap over it). With s = sum I_n sin d_n, c = sum I_n cos d_n,
the phase atan2(s, c) is 2 pi x / Q and the modulation (2 / N) |(s, c)| is the fringe's amplitude.

Unwrapping: the cue reads x_c, the fine fringes x_f (mod P); the period index is k = round((x_c -
x_f) / P) and x = k P + x_f. It holds while the cue errs by less than P / 2: the cue's noise is the
fine one's times C / P, so P cannot be small (64 px by default, 16 periods on a 1024-px projector).
A pixel whose cue lies further than `cue_margin` P from the result is dropped (the cue nearly
reached the next period). Where that is so of more than a twentieth of the lit pixels a warning says
so, and of more than a fifth the decode is refused (DecodeError): the cue is off everywhere, and
many kept periods would be wrong. A pixel is lit where the fringes' peak to trough (twice their
modulation, what a white less a dark frame would read) reaches `black_threshold`, and read where
both modulations reach `min_modulation`; its texture is twice the fine steps' mean (the white
frame's light, for fringes that span 0 to 1). With no white frame, undoing the camera's blur
(`deblur_px`), which finds its edges in one, is refused.

N = 3 needs a projector whose light is linear in the level: a DLP's 8-bit patterns, or any
projector through its calibrated response (`slrig calibrate response`). A video projector's gamma
adds a second harmonic that 3 steps read as a shift of the phase, of the cue as of the fringes (on
the simulated bench's gamma of 2.2, a third of the lit pixels' cue is off); 4 steps cancel it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from typing import Literal

import numpy as np
from pydantic import Field

from rig.errors import DecodeError
from rig.lazy import lazy_module
from rig.patterns.base import CodecParams
from rig.patterns.correspondence import Correspondence
from rig.patterns.lines import LineCodec
from rig.patterns.phase import step_weights, wrapped_steps
from rig.patterns.registry import register
from rig.patterns.saturation import saturated_in, without_saturated
from rig.patterns.stream import FrameStream, integer_frame
from rig.workers import in_row_strips

phase_kernels = lazy_module("rig.kernels.phase")  # numba compiles on first use: not for --help
log = logging.getLogger(__name__)

# a pixel's status (as rig.kernels.phase.cued_unwrap writes it), and one more: clipped in a frame
UNLIT, DECODED, CUE_OFF, OUTSIDE, LOW_MODULATION, SATURATED = 0, 1, 2, 3, 4, 5
CUE_OFF_WARNING = 0.05  # of the lit pixels: more whose cue is off is worth a warning ...
CUE_OFF_REFUSED = 0.2  # ... and this many, a refusal (a linear projector: 0.07 %; a gamma of 2.2: 33 %)
WARN_EVERY_S = 10.0  # live mode decodes 20 sequences a second: one warning in this long
_NONE_CLIPPED = np.zeros((0, 0), bool)  # what account_status is given where no pixel clipped (never read)


class CuedPhaseParams(CodecParams):
    directions: Literal["columns", "rows"] = Field("columns", description="the projector coordinate to code")
    steps: int = Field(3, ge=3, le=16, description="phase steps N of the fringes and of the cue")
    period_px: int = Field(64, ge=8, le=4096, description="fringe period P in projector pixels")
    min_modulation: float = Field(
        0.02, ge=0.0, le=1.0, description="least amplitude of the fringes and of the cue (fraction of full scale)"
    )
    cue_margin: float = Field(
        0.35, gt=0.0, lt=0.5, description="a pixel whose cue lies further than this many periods from it is dropped"
    )


@register
class CuedPhaseCodec(LineCodec):
    name = "cued_phase"
    Params = CuedPhaseParams
    params: CuedPhaseParams  # type: ignore[assignment]  # a LineCodec's axes, without its Gray settings

    _warned_s = -WARN_EVERY_S  # when this codec last warned (time.monotonic); set per instance then

    @property
    def axis(self) -> str:
        return self.axes()[0]

    @property
    def cue_period(self) -> int:
        return self.extent(self.axis) + self.params.period_px

    @property
    def needs_linear_light(self) -> bool:
        return self.params.steps == 3  # 4 steps and more cancel a gamma's second harmonic

    @property
    def frame_count(self) -> int:
        return self._coded_frame_count()  # no white or dark frame

    def iter_patterns(self) -> Iterator[np.ndarray]:
        for pattern in self._coded_iter():
            yield self._sent(pattern)

    def _coded_frame_count(self) -> int:
        return 2 * self.params.steps

    def _coded_lines(self) -> list[tuple[np.ndarray, str]]:
        x, steps = np.arange(self.extent(self.axis)), self.params.steps

        def fringe(period: int, n: int) -> np.ndarray:
            return np.rint(255 * (0.5 + 0.5 * np.cos(2 * np.pi * x / period - 2 * np.pi * n / steps))).astype(np.uint8)

        return [
            (fringe(period, n), self.axis) for period in (self.params.period_px, self.cue_period) for n in range(steps)
        ]

    def decode(self, frames: list[np.ndarray], full_scale: int) -> Correspondence:
        self.refuse_deblur()  # before the base class deblurs the frames
        return super().decode(frames, full_scale)

    def _decoded(self, frames: list[np.ndarray], full_scale: int) -> Correspondence:
        """The reference decoder (numpy), as the module docstring says; the stream's compiled passes
        give the same within float rounding."""
        steps, period = self.params.steps, np.float32(self.params.period_px)
        grey = [integer_frame(self, f).astype(np.float32) / np.float32(full_scale) for f in frames]
        fine, fine_modulation = _phase(grey[:steps], period)
        cue, cue_modulation = _phase(grey[steps:], np.float32(self.cue_period))
        extent = self.extent(self.axis)
        cue = np.where(cue > extent + period / 2, cue - np.float32(self.cue_period), cue)  # noise about 0
        coordinate = (np.floor((cue - fine) / period + np.float32(0.5)) * period + fine).astype(np.float32)
        status = np.where((coordinate > -0.5) & (coordinate < extent - 0.5), DECODED, OUTSIDE)
        status = np.where(np.abs(coordinate - cue) <= self.params.cue_margin * period, status, CUE_OFF)
        status = np.where(
            np.minimum(fine_modulation, cue_modulation) >= self.params.min_modulation, status, LOW_MODULATION
        )
        status = np.where(2 * fine_modulation >= self.params.black_threshold, status, UNLIT)
        peak = texture(frames[:steps], full_scale)
        saturated = saturated_in(frames, full_scale)
        return self.accounted(coordinate, status.astype(np.uint8), saturated, fine_modulation, peak, full_scale)

    def _decode(self, *_: object) -> Correspondence:  # _decoded reads the frames itself: no white or dark
        raise NotImplementedError

    def references(self, frames: list[np.ndarray], corr: Correspondence) -> tuple[np.ndarray, np.ndarray]:
        """The white and dark frames the spill screen would take: the fringes' peak and trough."""
        if corr.texture is None:
            raise DecodeError(f"{self.name}: a correspondence without its texture has no references")
        return corr.texture, trough(corr.texture, corr.quality, corr.full_scale)

    def refuse_deblur(self) -> None:
        if self.deblur_px > 0:
            raise DecodeError(
                f"{self.name}: scan.exposure.deblur_px finds the edges it undoes in a white frame, and this codec "
                "shows none: set it to 0, or scan with another codec"
            )

    def accounted(
        self,
        coordinate: np.ndarray,
        status: np.ndarray,
        saturated: np.ndarray | None,
        quality: np.ndarray,
        peak: np.ndarray,
        full_scale: int,
    ) -> Correspondence:
        """The Correspondence from each pixel's status (rig.kernels.phase.cued_unwrap's): a lit pixel
        clipped in any frame counts as saturated, whatever else it read (a clipped step throws its
        cue off too); the coordinates NaN where not decoded."""
        valid, parts = np.empty(status.shape, bool), []
        clipped = saturated is not None and bool(saturated.any())
        marks = saturated if saturated is not None and clipped else _NONE_CLIPPED
        in_row_strips(
            status.shape[0],
            lambda rows: parts.append(
                phase_kernels.account_status(status, marks, clipped, coordinate, valid, rows.start, rows.stop)
            ),
        )
        found = np.sum(parts, axis=0)
        names = {
            "decoded": DECODED,
            "cue_off": CUE_OFF,
            "low_modulation": LOW_MODULATION,
            "rejected_saturated": SATURATED,
        }
        counts = {"lit": int(found[1:].sum()), **{name: int(found[code]) for name, code in names.items()}}
        self._judge_cue(counts)
        corr = Correspondence(
            valid=valid, quality=quality, texture=peak, counts=counts, full_scale=full_scale,
            **{self.axis: coordinate},  # type: ignore[arg-type]
        )  # fmt: skip
        return corr if not clipped else without_saturated(corr, saturated)

    def _judge_cue(self, counts: dict[str, int]) -> None:
        """DecodeError where the cue is off at over CUE_OFF_REFUSED of the lit pixels; a warning
        (at most one every WARN_EVERY_S) over CUE_OFF_WARNING."""
        off = counts["cue_off"] / max(counts["lit"], 1)
        if off <= CUE_OFF_WARNING:
            return
        said = (
            f"{self.name}: the cue disagrees with the fringes at {100 * off:.1f} % of the lit pixels: the projector's "
            "light is not linear in the level (3 steps misread a gamma: calibrate its response with slrig calibrate "
            "response, or take 4 steps), or the scene moved between the fringes and the cue"
        )
        if off > CUE_OFF_REFUSED:  # periods read wrong at many of the rest: no points rather than wrong ones
            raise DecodeError(said)
        if time.monotonic() - self._warned_s >= WARN_EVERY_S:
            self._warned_s = time.monotonic()
            log.warning(said)

    def stream(self, full_scale: int) -> FrameStream:
        return CuedPhaseStream(self, full_scale)


def _phase(steps: list[np.ndarray], period: np.float32) -> tuple[np.ndarray, np.ndarray]:
    """The coordinate in [0, period) the steps (fractions of full scale) read, and their modulation."""
    delta = 2 * np.pi * np.arange(len(steps)) / len(steps)
    s = sum(step * np.float32(np.sin(d)) for step, d in zip(steps, delta, strict=True))
    c = sum(step * np.float32(np.cos(d)) for step, d in zip(steps, delta, strict=True))
    angle = np.mod(np.arctan2(s, c), 2 * np.pi).astype(np.float32)
    return angle * (period / np.float32(2 * np.pi)), np.float32(2 / len(steps)) * np.sqrt(s * s + c * c)


def texture(fine: list[np.ndarray], full_scale: int) -> np.ndarray:
    """Twice the fine steps' mean, in the frames' sample type (each channel of a colour frame); a
    grey frame's in one compiled pass (rig.kernels.phase.twice_mean), the same sums."""
    if fine[0].ndim == 2:
        out, frames = np.empty(fine[0].shape, fine[0].dtype), tuple(np.ascontiguousarray(f) for f in fine)
        in_row_strips(
            out.shape[0],
            lambda rows: phase_kernels.twice_mean(frames, np.float32(full_scale), out, rows.start, rows.stop),
        )
        return out
    total = np.zeros(fine[0].shape, np.float32)
    for frame in fine:
        total += frame
    return np.minimum(total * np.float32(2 / len(fine)), full_scale).astype(fine[0].dtype)


def trough(peak: np.ndarray, modulation: np.ndarray, full_scale: int) -> np.ndarray:
    """The fringes' trough (H, W) in counts: their peak (one channel: a colour peak's mean) less
    twice their modulation (a fraction of `full_scale`)."""
    grey = peak.astype(np.float32)
    if grey.ndim == 3:
        grey = grey.mean(axis=2)
    return np.maximum(grey - 2 * modulation * np.float32(full_scale), np.float32(0))


class CuedPhaseStream(FrameStream):
    """The fine steps held until the last one, then read in one pass into the wrapped phase and
    the modulation (rig.patterns.phase.wrapped_steps), and the texture made while the cue's frames
    come; the cue's steps likewise, read with the unwrapping in one pass
    (rig.kernels.phase.cued_unwrap). The spill screen, where the codec has one, takes the fringes'
    peak and trough for the white and dark frames it looks at."""

    codec: CuedPhaseCodec

    def __init__(self, codec: CuedPhaseCodec, full_scale: int) -> None:
        codec.refuse_deblur()
        super().__init__(codec, full_scale)
        self._weights = step_weights(codec.params.steps, full_scale)
        self._fine: list[np.ndarray] = []  # as captured, for the texture
        self._peak: np.ndarray | None = None  # the texture
        self._held: list[np.ndarray] = []  # the current period's steps in integer counts
        self._wrapped: tuple[np.ndarray, np.ndarray] | None = None  # fine coordinate (mod P), modulation
        self._result: tuple[np.ndarray, np.ndarray] | None = None  # coordinate, status

    def _consume(self, index: int, frame: np.ndarray) -> None:
        steps = self.codec.params.steps
        if index < steps:
            self._fine.append(frame)
        self._held.append(np.ascontiguousarray(integer_frame(self.codec, frame)))
        if len(self._held) == steps:
            held, self._held = tuple(self._held), []
            if self._wrapped is None:  # the texture too, while the cue's frames are still to come
                fraction, _, modulation = wrapped_steps(held, self._weights, self.codec.params.period_px)
                self._wrapped, self._peak, self._fine = (fraction, modulation), texture(self._fine, self.full_scale), []
            else:
                self._result = self._unwrap(held)

    def _unwrap(self, held: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        if self._wrapped is None:
            raise DecodeError(f"{self.codec.name}: the cue came before the fringes")
        coordinate, modulation = self._wrapped  # the coordinate is written over the fine fraction
        params, codec = self.codec.params, self.codec
        status = np.empty(coordinate.shape, np.uint8)
        in_row_strips(
            coordinate.shape[0],
            lambda rows: phase_kernels.cued_unwrap(
                held, self._weights[0], self._weights[1], np.float32(codec.cue_period),
                np.float32(params.period_px), codec.extent(codec.axis), np.float32(params.black_threshold),
                np.float32(params.min_modulation), np.float32(params.cue_margin), modulation, coordinate, status,
                rows.start, rows.stop,
            ),
        )  # fmt: skip
        return coordinate, status

    def _finish(self) -> Correspondence:
        if self._result is None or self._wrapped is None or self._peak is None:
            raise DecodeError(f"{self.codec.name}: the stream finished before its last frame")
        coordinate, status = self._result
        peak, modulation = self._peak, self._wrapped[1]
        saturated = self.saturation.mask if self.saturation.clipped else None  # no mask made where none clipped
        corr = self.codec.accounted(coordinate, status, saturated, modulation, peak, self.full_scale)
        if self.spill is not None:  # the white and dark frames it takes, as the batch decoder's (Codec.references)
            for index, reference in enumerate(self.codec.references([], corr)):
                self.spill.add(index, reference)
        return corr
