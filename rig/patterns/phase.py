"""`phase`: N-step phase shift, unwrapped by a complementary Gray code.

Pattern n for projector coordinate x (pixel centres at integers) is
    0.5 + 0.5 cos(2 pi x / P - 2 pi n / N)
so phi = atan2(sum I_n sin d_n, sum I_n cos d_n) = 2 pi x / P (mod 2 pi).

Unwrapping: a Gray code of the half-period index h = floor(x / (P / 2)) (one bit more than the
period index) gives two period estimates, k1 = h >> 1 with edges at period edges and
k2 = (h + 1) >> 1 with edges at mid-periods. Near a wrap of the phase (phi < pi/2 or > 3pi/2) k2
is used, away from it k1: neither is read near its own edges, so a one-pixel disagreement between
the Gray edges and the phase wrap never makes a 2 pi jump.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, field_validator

from rig.lazy import lazy_module
from rig.patterns.base import even_period
from rig.patterns.correspondence import Correspondence, NormalizedFrames, least_counts
from rig.patterns.graycode import bit_count, decode_gray, gray_planes, planes_with_inverses
from rig.patterns.lines import LineCodec, LineParams
from rig.patterns.registry import register
from rig.patterns.spec import Frequency, GrayCode, PatternSpec, PhaseShift, ProjectorSpace
from rig.patterns.stream import DenseBase, FrameStream, GrayBits
from rig.workers import in_row_strips

phase_kernels = lazy_module("rig.kernels.phase")  # numba compiles on first use: not for --help


class PhaseParams(LineParams):
    steps: int = Field(8, ge=3, le=64, description="phase steps N per period")
    period_px: int = Field(16, ge=4, le=4096, description="fringe period P in projector pixels (even)")
    min_modulation: float = Field(
        0.02,
        ge=0.0,
        le=1.0,
        description="minimum fringe amplitude B (fraction of full scale)",
    )

    _even_period = field_validator("period_px")(even_period)


@register
class PhaseCodec(LineCodec):
    name = "phase"
    Params = PhaseParams
    params: PhaseParams

    def description(self) -> PatternSpec:
        """This codec's frames as a pattern description (rig.patterns.spec)."""
        axes = tuple("columns" if axis == "u" else "rows" for axis in self.axes())
        frequency = Frequency(period_px=self.params.period_px, steps=self.params.steps)
        return PatternSpec(
            projector=ProjectorSpace(resolution=(self.width, self.height)),
            phase=PhaseShift(
                axes=axes,
                frequencies=[frequency],
                shift="minus",
                unwrap="gray",
                gray_unit="half_period",
                min_modulation=self.params.min_modulation,
            ),
            gray=GrayCode(
                axes=axes,
                white_black="first",
                min_contrast=self.params.white_threshold,
                black_threshold=self.params.black_threshold,
            ),
        )

    def _gray_bits(self, axis: str) -> int:
        halves = math.ceil(self.extent(axis) / (self.params.period_px // 2))
        return bit_count(halves)

    def _coded_frame_count(self) -> int:
        return sum(self.params.steps + 2 * self._gray_bits(axis) for axis in self.axes())

    def _coded_lines(self) -> list[tuple[np.ndarray, str]]:
        n_steps, period = self.params.steps, self.params.period_px
        out: list[tuple[np.ndarray, str]] = []
        for axis in self.axes():
            x = np.arange(self.extent(axis))
            for n in range(n_steps):
                value = 0.5 + 0.5 * np.cos(2 * np.pi * x / period - 2 * np.pi * n / n_steps)
                out.append((np.rint(value * 255).astype(np.uint8), axis))
            half_index = x // (period // 2)
            out += [(line, axis) for line in planes_with_inverses(gray_planes(half_index, self._gray_bits(axis)))]
        return out

    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        n_steps, period = self.params.steps, self.params.period_px
        delta = 2 * np.pi * np.arange(n_steps) / n_steps
        sin_d, cos_d = np.sin(delta).astype(np.float32), np.cos(delta).astype(np.float32)
        valid = lit.copy()
        quality = np.full(lit.shape, np.inf, dtype=np.float32)
        coords: dict[str, np.ndarray] = {}
        counts = {"lit": int(lit.sum())}
        offset = 0
        for axis in self.axes():
            s = np.zeros(lit.shape, dtype=np.float32)
            c = np.zeros(lit.shape, dtype=np.float32)
            for n in range(n_steps):
                s += frames[offset + n] * sin_d[n]
                c += frames[offset + n] * cos_d[n]
            offset += n_steps
            modulation = (2.0 / n_steps) * np.sqrt(s * s + c * c)
            phi = np.mod(np.arctan2(s, c), 2 * np.pi)
            bits = self._gray_bits(axis)
            half, strength = decode_gray(frames[offset : offset + 2 * bits], bits)
            offset += 2 * bits
            k1 = half >> 1
            k2 = (half + 1) >> 1
            k = np.where(phi < np.pi / 2, k2, np.where(phi > 1.5 * np.pi, k2 - 1, k1))
            x = (k + phi / (2 * np.pi)) * period
            ok = (modulation >= self.params.min_modulation) & (strength >= self.params.white_threshold)
            ok &= (x > -0.5) & (x < self.extent(axis) - 0.5)
            counts[f"low_modulation_{axis}"] = int((lit & (modulation < self.params.min_modulation)).sum())
            valid &= ok
            quality = np.minimum(quality, modulation)
            coords[axis] = x.astype(np.float32)
        return self.correspondence(coords, valid, quality, texture, counts)

    def stream(self, full_scale: int) -> FrameStream:
        return PhaseStream(self, full_scale)


class PhaseStream(FrameStream):
    """The phase decoder fed frame by frame: a period's steps are held until its last step arrives
    and are then read in one pass into the wrapped phase and the modulation (rig.kernels.phase), each
    Gray pair is read in integer counts as it arrives (GrayBits); after the last pair only the
    unwrapping remains. The steps are summed in the batch decoder's order, but with weights scaled
    by full scale and the phase from a polynomial atan2: coordinates agree within float rounding."""

    codec: PhaseCodec

    def __init__(self, codec: PhaseCodec, full_scale: int) -> None:
        super().__init__(codec, full_scale)
        self._weights = step_weights(codec.params.steps, full_scale)
        self._pending = [(axis, GrayBits(codec._gray_bits(axis))) for axis in codec.axes()]  # axes still to read
        self._min_strength = least_counts(codec.params.white_threshold, full_scale)
        self._base = DenseBase(codec, full_scale, keep_contrast=False)
        self._coords: dict[str, np.ndarray] = {}
        self._quality: np.ndarray | None = None
        self._reset_axis()

    def _reset_axis(self) -> None:
        self._steps: list[np.ndarray] = []  # the current period's steps, until its last one
        self._wrapped: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # fraction, near a wrap, modulation

    def _consume(self, index: int, frame: np.ndarray) -> None:
        image = self._base.coded_frame(index, frame)
        if image is None:
            return
        axis, reader = self._pending[0]
        if self._wrapped is None:
            self._steps.append(np.ascontiguousarray(image))
            if len(self._steps) == self.codec.params.steps:
                self._wrap()
        elif reader.take(image):
            self._coords[axis] = self._unwrap(axis, reader)
            self._pending.pop(0)
            self._reset_axis()

    def _wrap(self) -> None:
        """After a period's last step: the modulation, and the phase as a fraction of a period
        ready for the period index (near a wrap, the index of the code shifted by half a period)."""
        steps, self._steps = tuple(self._steps), []
        self._wrapped = wrapped_steps(steps, self._weights, self.codec.params.period_px)

    def _unwrap(self, axis: str, reader: GrayBits) -> np.ndarray:
        assert self._wrapped is not None
        fraction, near, modulation = self._wrapped
        half, strength = reader.value(), reader.strength()
        params, base = self.codec.params, self._base
        assert base.lit is not None and base.valid is not None
        lit, valid = base.lit, base.valid
        period, extent = np.float32(params.period_px), self.codec.extent(axis)
        quality = modulation if self._quality is None else self._quality
        low: list[int] = []
        in_row_strips(
            half.shape[0],
            lambda rows: low.append(
                phase_kernels.phase_unwrap(
                    half,
                    near,
                    fraction,
                    modulation,
                    strength,
                    period,
                    params.min_modulation,
                    self._min_strength,
                    extent,
                    lit,
                    valid,
                    quality,
                    quality is not modulation,
                    rows.start,
                    rows.stop,
                )
            ),
        )
        base.narrowed(f"low_modulation_{axis}", sum(low), fraction)
        self._quality = quality
        return fraction  # now the coordinate

    def _finish(self) -> Correspondence:
        assert self._quality is not None
        return self._base.correspondence(self._coords, self._quality)


def step_weights(steps: int, full_scale: int) -> tuple[np.ndarray, np.ndarray]:
    """The sine and cosine weights of N phase steps in integer counts (of `full_scale`)."""
    delta = 2 * np.pi * np.arange(steps) / steps
    return (np.sin(delta) / full_scale).astype(np.float32), (np.cos(delta) / full_scale).astype(np.float32)


def wrapped_steps(
    steps: tuple[np.ndarray, ...], weights: tuple[np.ndarray, np.ndarray], period_px: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A period's steps read whole (rig.kernels.phase.phase_wrap): the phase as a fraction of the
    period in pixels (one period less past 3 pi / 2), whether it is near a wrap, and the modulation."""
    shape = steps[0].shape
    fraction, modulation, near = np.empty(shape, np.float32), np.empty(shape, np.float32), np.empty(shape, np.uint8)
    amplitude, period = np.float32(2.0 / len(steps)), np.float32(period_px)
    in_row_strips(
        shape[0],
        lambda rows: phase_kernels.phase_wrap(
            steps, weights[0], weights[1], amplitude, period, modulation, near, fraction, rows.start, rows.stop
        ),
    )
    return fraction, near, modulation
