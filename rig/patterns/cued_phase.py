"""`cued_phase`: N-step phase shift at the fringe period, unwrapped by N steps of a single period
that spans the projector (a cue), and nothing else: 2N frames, 6 at N = 3, with no white or dark
frame (the fringes give the lit mask and the texture themselves). The shortest sequence slrig
shows, for live mode at a camera's full rate (SLStudio's "phase shift 2 x 3" is the same idea).

Pattern n of a period Q, for projector coordinate x (pixel centres at integers), is
    0.5 + 0.5 cos(2 pi x / Q - 2 pi n / N),
first at Q = P (the fine fringes), then at Q = C = extent + P (the cue; one period more than the
projector, so that its phase does not wrap over it). With s = sum I_n sin d_n, c = sum I_n cos d_n,
the phase atan2(s, c) is 2 pi x / Q and the modulation (2 / N) |(s, c)| is the fringe's amplitude.

Unwrapping: the cue reads x_c, the fine fringes x_f (mod P); the period index is
k = round((x_c - x_f) / P) and x = k P + x_f. It holds while the cue errs by less than P / 2: the
cue's noise is the fine one's times C / P, so P cannot be small (64 px by default, 16 periods on a
1024-px projector). A pixel whose cue lies further than `cue_margin` P from the result is dropped
(the cue nearly reached the next period); where that is so of more than a fifth of the lit
pixels, the decode is refused (DecodeError): the cue is off everywhere, and many kept periods are
wrong. A pixel is lit where both modulations reach `min_modulation`; its texture is twice the fine
steps' mean (the white frame's light, for fringes that span 0 to 1).

N = 3 needs a projector whose light is linear in the level: a DLP's 8-bit patterns, or any
projector through its calibrated response (`slrig calibrate response`). A video projector's gamma
adds a second harmonic that 3 steps read as a shift of the phase, of the cue as of the fringes (on
the simulated bench's gamma of 2.2, a third of the lit pixels' cue is off); 4 steps cancel it.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterator
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from rig.errors import DecodeError
from rig.lazy import lazy_module
from rig.patterns.base import Correspondence, even_period
from rig.patterns.deblur import Deblur
from rig.patterns.lines import LineCodec, LineParams
from rig.patterns.registry import register
from rig.patterns.saturation import saturated_in, without_saturated
from rig.patterns.spill import without_outshone
from rig.patterns.stream import FrameStream, integer_frame
from rig.workers import in_row_strips

fused_phase = lazy_module("rig.fused_phase")  # numba compiles on first use: not for --help
log = logging.getLogger(__name__)

# a pixel's status (as rig.fused_phase.cued_unwrap writes it), and one more: clipped in a frame
UNLIT, DECODED, CUE_OFF, OUTSIDE, SATURATED = 0, 1, 2, 3, 4
CUE_OFF_WARNING = 0.05  # of the lit pixels: more whose cue is off is worth a warning ...
CUE_OFF_REFUSED = 0.2  # ... and this many, a refusal (a linear projector: 0.07 %; a gamma of 2.2: 33 %)


class CuedPhaseParams(LineParams):
    directions: Literal["columns", "rows"] = Field("columns", description="the projector coordinate to code")  # type: ignore[assignment]
    steps: int = Field(3, ge=3, le=16, description="phase steps N of the fringes and of the cue")
    period_px: int = Field(64, ge=8, le=4096, description="fringe period P in projector pixels (even)")
    min_modulation: float = Field(
        0.02,
        ge=0.0,
        le=1.0,
        description="least fringe amplitude of the fringes and of the cue (fraction of full scale)",
    )
    cue_margin: float = Field(
        0.35, gt=0.0, lt=0.5, description="a pixel whose cue lies further than this many periods from it is dropped"
    )

    _even_period = field_validator("period_px")(even_period)


@register
class CuedPhaseCodec(LineCodec):
    name = "cued_phase"
    Params = CuedPhaseParams
    params: CuedPhaseParams

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
        """The reference decoder (numpy), as the module docstring says; the stream's compiled passes
        give the same within float rounding."""
        if len(frames) != self.frame_count:
            raise DecodeError(f"{self.name}: expected {self.frame_count} frames, got {len(frames)}")
        if len({f.shape[:2] for f in frames}) != 1:
            raise DecodeError(f"{self.name}: frames differ in size: {sorted({f.shape[:2] for f in frames})}")
        if self.deblur_px > 0:
            restore = Deblur(self.deblur_px, full_scale).restored
            frames = [restore(f) for f in frames]
        steps, period = self.params.steps, np.float32(self.params.period_px)
        grey = [integer_frame(self, f).astype(np.float32) / np.float32(full_scale) for f in frames]
        fine, fine_modulation = _phase(grey[:steps], period)
        cue, cue_modulation = _phase(grey[steps:], np.float32(self.cue_period))
        extent = self.extent(self.axis)
        cue = np.where(cue > extent + period / 2, cue - np.float32(self.cue_period), cue)  # noise about 0
        k = np.floor((cue - fine) / period + np.float32(0.5))
        coordinate = (k * period + fine).astype(np.float32)
        status = np.where((coordinate > -0.5) & (coordinate < extent - 0.5), DECODED, OUTSIDE)
        status = np.where(np.abs(coordinate - cue) <= self.params.cue_margin * period, status, CUE_OFF)
        status = np.where(np.minimum(fine_modulation, cue_modulation) >= self.params.min_modulation, status, UNLIT)
        peak = texture(frames[:steps], full_scale)
        corr = self.accounted(
            coordinate, status.astype(np.uint8), saturated_in(frames, full_scale), fine_modulation, peak
        )
        if self.drops_outshone:
            trough = np.maximum(peak.astype(np.float32) - 2 * fine_modulation * np.float32(full_scale), 0)
            corr = without_outshone(corr, peak, trough)
        return dataclasses.replace(corr, full_scale=full_scale)

    def accounted(
        self,
        coordinate: np.ndarray,
        status: np.ndarray,
        saturated: np.ndarray | None,
        quality: np.ndarray,
        peak: np.ndarray,
    ) -> Correspondence:
        """The Correspondence from each pixel's status (rig.fused_phase.cued_unwrap's): a lit pixel
        clipped in any frame counts as saturated, whatever else it read (a clipped step throws its
        cue off too); the coordinates NaN where not decoded."""
        if saturated is not None:
            status[saturated & (status != UNLIT)] = SATURATED
        found = np.bincount(status.ravel(), minlength=SATURATED + 1)
        counts = {
            "lit": int(found[1:].sum()),
            "cue_off": int(found[CUE_OFF]),
            "rejected_saturated": int(found[SATURATED]),
        }
        valid = status == DECODED
        coordinate[~valid] = np.nan
        counts["decoded"] = int(found[DECODED])
        off = found[CUE_OFF] / max(counts["lit"], 1)
        if off > CUE_OFF_WARNING:
            said = (
                f"{self.name}: the cue disagrees with the fringes at {100 * off:.1f} % of the lit pixels: a projector "
                "whose light is not linear in the level shifts a 3-step cue (calibrate its response: slrig calibrate "
                "response; or take 4 steps)"
            )
            if off > CUE_OFF_REFUSED:  # periods read wrong at many of the rest: no points rather than wrong ones
                raise DecodeError(said)
            log.warning(said)
        corr = Correspondence(valid=valid, quality=quality, texture=peak, counts=counts, **{self.axis: coordinate})  # type: ignore[arg-type]
        return corr if saturated is None else without_saturated(corr, saturated)

    def _decode(self, *_: object) -> Correspondence:  # decode() reads the frames itself: no white or dark
        raise NotImplementedError

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
    """Twice the fine steps' mean, in the frames' sample type (each channel of a colour frame)."""
    total = np.zeros(fine[0].shape, np.float32)
    for frame in fine:
        total += frame
    return np.minimum(total * np.float32(2 / len(fine)), full_scale).astype(fine[0].dtype)


class CuedPhaseStream(FrameStream):
    """The fine steps held until the last one, then read in one pass into the wrapped phase and
    the modulation (rig.fused_phase.phase_wrap); the cue's steps likewise, read with the unwrapping
    in one pass (rig.fused_phase.cued_unwrap). The spill screen, where the codec has one, takes the
    fringes' peak and trough for the white and dark frames it looks at."""

    codec: CuedPhaseCodec

    def __init__(self, codec: CuedPhaseCodec, full_scale: int) -> None:
        super().__init__(codec, full_scale)
        delta = 2 * np.pi * np.arange(codec.params.steps) / codec.params.steps
        self._weight_sin = (np.sin(delta) / full_scale).astype(np.float32)
        self._weight_cos = (np.cos(delta) / full_scale).astype(np.float32)
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
                self._wrapped, self._peak, self._fine = self._wrap(held), texture(self._fine, self.full_scale), []
            else:
                self._result = self._unwrap(held)

    def _wrap(self, held: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        shape = held[0].shape
        fraction, modulation, near = np.empty(shape, np.float32), np.empty(shape, np.float32), np.empty(shape, np.uint8)
        amplitude, period = np.float32(2.0 / len(held)), np.float32(self.codec.params.period_px)
        in_row_strips(
            shape[0],
            lambda rows: fused_phase.phase_wrap(
                held, self._weight_sin, self._weight_cos, amplitude, period, modulation, near, fraction,
                rows.start, rows.stop,
            ),
        )  # fmt: skip
        return fraction, modulation

    def _unwrap(self, held: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        assert self._wrapped is not None
        coordinate, modulation = self._wrapped  # the coordinate is written over the fine fraction
        params, codec = self.codec.params, self.codec
        status = np.empty(coordinate.shape, np.uint8)
        in_row_strips(
            coordinate.shape[0],
            lambda rows: fused_phase.cued_unwrap(
                held, self._weight_sin, self._weight_cos, np.float32(codec.cue_period),
                np.float32(params.period_px), codec.extent(codec.axis), np.float32(params.min_modulation),
                np.float32(params.cue_margin), modulation, coordinate, status, rows.start, rows.stop,
            ),
        )  # fmt: skip
        return coordinate, status

    def _finish(self) -> Correspondence:
        assert self._result is not None and self._wrapped is not None and self._peak is not None
        coordinate, status = self._result
        peak, modulation = self._peak, self._wrapped[1]
        if self.spill is not None:  # the white and dark frames it would take: the fringes' peak and trough
            self.spill.add(0, peak)
            self.spill.add(1, np.maximum(peak.astype(np.float32) - 2 * modulation * np.float32(self.full_scale), 0))
        return self.codec.accounted(coordinate, status, self.saturation.mask, modulation, peak)
