"""`radial`: dense circular fringes giving (R, theta), so a projector point at every camera pixel.

Frames after white and black:
- radial N-step phase shift, 0.5 + 0.5 cos(2 pi rho / P - 2 pi n / N), rho the distance from the
  centre in projector pixels;
- a Gray code of the half-period annulus index floor(rho / (P / 2)), unwrapping the radial phase the
  way `phase` unwraps columns (complementary code: never read near its own edges);
- angular phase in three levels, 0.5 + 0.5 cos(M theta - 2 pi n / N): one period per revolution
  (absolute), `mid_periods`, then `angle_periods` periods, each unwrapped by the level before. The
  fine level makes the tangential precision R * sigma_theta comparable to the radial one.

Projector point: (u, v) = centre + R (cos theta, sin theta); triangulated ray to ray. Near the centre
the angular fringes are finer than the optics resolve; their modulation falls below the threshold
and those pixels are masked.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from pydantic import Field, field_validator

from rig.lazy import lazy_module
from rig.patterns.base import CodecParams, PixelCoord, even_period
from rig.patterns.circular import CircularCodec
from rig.patterns.correspondence import Correspondence, NormalizedFrames, least_counts
from rig.patterns.fringes import RunningSums, fringe_images, summed
from rig.patterns.graycode import bit_count, decode_gray, gray_images
from rig.patterns.phase import step_weights
from rig.patterns.registry import register
from rig.patterns.stream import DenseBase, FrameStream, GrayBits
from rig.workers import in_row_strips

radial_kernels = lazy_module("rig.kernels.radial")  # numba compiles on first use: not for --help
# a level's steps (integer counts) and their sine and cosine weights (scaled to the counts)
Steps = tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray]


class RadialParams(CodecParams):
    center_px: tuple[PixelCoord, PixelCoord] | None = Field(
        None, description="fringe centre; default: the image centre"
    )
    steps: int = Field(8, ge=3, le=64, description="radial phase steps")
    period_px: int = Field(16, ge=4, le=4096, description="radial fringe period P in projector pixels (even)")
    angle_periods: int = Field(128, ge=1, le=4096, description="angular fringe periods per revolution (fine level)")
    mid_periods: int = Field(12, ge=1, le=4096, description="angular periods of the middle unwrapping level")
    angle_steps: int = Field(8, ge=3, le=64, description="phase steps of the fine angular level")
    coarse_steps: int = Field(4, ge=3, le=64, description="phase steps of the coarse and middle angular levels")
    min_modulation: float = Field(0.02, ge=0.0, le=1.0, description="minimum fringe amplitude (fraction of full scale)")
    min_fringe_period_px: float = Field(
        3.0,
        ge=2.0,
        le=1000.0,
        description="an angular level is used only where its period (2 pi R / periods) is at least this: "
        "finer fringes alias in the camera; nearer the centre theta comes from a coarser level",
    )
    white_threshold: float = Field(0.02, ge=0.0, le=1.0, description="minimum |pattern - inverse| of the Gray code")
    max_unwrap_disagreement: float = Field(
        0.25,
        gt=0.0,
        le=0.5,
        description="mask a pixel where an angular level and the level before it disagree by more than this "
        "many periods (mixed pixels on depth edges): its period count would be a guess",
    )

    _even_period = field_validator("period_px")(even_period)


def _phase(sums: RunningSums) -> tuple[np.ndarray, np.ndarray]:
    """Wrapped phase in [0, 2 pi) and modulation of a level's summed steps."""
    s, c = sums.s, sums.c
    return np.mod(np.arctan2(s, c), 2 * np.pi), (2.0 / sums.steps) * np.sqrt(s * s + c * c)


def _unwrap(wrapped: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Absolute phase from a wrapped one and an absolute estimate of it, and the disagreement of the
    two in periods (0 is perfect agreement; near 0.5 the period count is a guess)."""
    periods = (reference - wrapped) / (2 * np.pi)
    whole = np.round(periods)
    return wrapped + 2 * np.pi * whole, np.abs(periods - whole)


@register
class RadialCodec(CircularCodec):
    name = "radial"
    Params = RadialParams
    params: RadialParams

    def coded_axes(self) -> str:
        return "uv"

    def _gray_bits(self) -> int:
        return bit_count(math.ceil((self.reach + 1) / (self.params.period_px // 2)))

    def _angular_levels(self) -> list[tuple[int, int]]:
        p = self.params
        return [(1, p.coarse_steps), (p.mid_periods, p.coarse_steps), (p.angle_periods, p.angle_steps)]

    def _coded_frame_count(self) -> int:
        return self.params.steps + 2 * self._gray_bits() + sum(steps for _, steps in self._angular_levels())

    def _coded_iter(self) -> Iterator[np.ndarray]:
        """The coded patterns one at a time, each made as its turn comes (rings' _coded_iter)."""
        p = self.params
        rho = self.radius()
        phase = 2 * np.pi * rho
        phase /= p.period_px  # in place, as every image-sized step here: a temporary fewer
        yield from fringe_images(phase, p.steps)
        del phase
        half_periods = rho / (p.period_px // 2)
        del rho
        index = np.floor(half_periods, out=half_periods).astype(np.int64)
        del half_periods
        yield from gray_images(index, self._gray_bits())
        del index
        theta = self.angle()
        for periods, steps in self._angular_levels():
            yield from fringe_images(periods * theta, steps)

    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        p = self.params
        bits = self._gray_bits()
        half, strength = decode_gray(frames[p.steps : p.steps + 2 * bits], bits)
        decoding = RadialDecoding.from_sums(self, lit, summed(frames, 0, p.steps), half, strength >= p.white_threshold)
        first = p.steps + 2 * bits
        for periods, steps in self._angular_levels():
            decoding.add_level(periods, summed(frames, first, steps))
            first += steps
        return decoding.correspondence(texture)

    def stream(self, full_scale: int) -> FrameStream:
        return RadialStream(self, full_scale)


class RadialDecoding:
    """The radial decode a level at a time, as the batch decoder and the stream both feed it: the
    radius from the radial phase and its Gray code, then theta refined by each angular level."""

    def __init__(
        self, codec: RadialCodec, lit: np.ndarray, radius: np.ndarray, radial_mod: np.ndarray, gray_strong: np.ndarray
    ) -> None:
        self.codec, self.lit, self.gray_strong = codec, lit, gray_strong
        self.radius, self.radial_mod = radius, radial_mod
        self.theta = np.zeros(lit.shape, dtype=np.float64)
        self.consistent = np.ones(lit.shape, dtype=bool)
        self.angular_mod = np.full(lit.shape, np.inf, dtype=np.float32)
        self.levels = 0

    @classmethod
    def from_sums(
        cls, codec: RadialCodec, lit: np.ndarray, radial: RunningSums, half: np.ndarray, gray_strong: np.ndarray
    ) -> RadialDecoding:
        """From the radial phase's summed steps and the half-period index of its Gray code."""
        period = codec.params.period_px
        phi, radial_mod = _phase(radial)
        k1, k2 = half >> 1, (half + 1) >> 1
        k = np.where(phi < np.pi / 2, k2, np.where(phi > 1.5 * np.pi, k2 - 1, k1))
        return cls(codec, lit, (k + phi / (2 * np.pi)) * period, radial_mod, gray_strong)

    @classmethod
    def from_steps(
        cls, codec: RadialCodec, lit: np.ndarray, steps: Steps, half: np.ndarray, gray_strong: np.ndarray
    ) -> RadialDecoding:
        """from_sums from the radial phase's steps (integer counts, their weights), in one compiled
        pass (rig.kernels.radial.radial_radius)."""
        radius, radial_mod = np.empty(lit.shape, np.float64), np.empty(lit.shape, np.float32)
        period = float(codec.params.period_px)
        in_row_strips(
            lit.shape[0],
            lambda rows: radial_kernels.radial_radius(*steps, half, period, radius, radial_mod, rows.start, rows.stop),
        )
        return cls(codec, lit, radius, radial_mod, gray_strong)

    def add_level(self, periods: int, sums: RunningSums) -> None:
        """An angular level's summed steps: the first gives theta, each later one refines it where
        its fringes are coarse enough to read."""
        p = self.codec.params
        wrapped, modulation = _phase(sums)
        self.levels += 1
        if self.levels == 1:
            self.theta, self.angular_mod = wrapped.astype(np.float64), modulation
            return
        usable = 2 * np.pi * self.radius / periods >= p.min_fringe_period_px
        refined, disagreement = _unwrap(wrapped, self.theta * periods)
        self.theta = np.where(usable, refined / periods, self.theta)
        self.angular_mod = np.where(usable, np.minimum(self.angular_mod, modulation), self.angular_mod)
        self.consistent &= ~usable | (disagreement <= p.max_unwrap_disagreement)

    def add_level_steps(self, periods: int, steps: Steps) -> None:
        """add_level from a level's steps (integer counts, their weights), in one compiled pass
        (rig.kernels.radial.angular_level)."""
        first = self.levels == 0
        self.levels += 1
        if first:
            self.angular_mod = np.empty(self.lit.shape, np.float32)
        arrays = (self.radius, self.theta, self.angular_mod, self.consistent)
        level = self._level(periods)
        in_row_strips(
            self.lit.shape[0],
            lambda rows: radial_kernels.angular_level(*steps, first, level, *arrays, rows.start, rows.stop),
        )

    def _level(self, periods: int) -> tuple[float, float, float]:
        """A level as the compiled passes take it: its periods, the least fringe period it is read
        at, and the disagreement with the level before that it allows."""
        p = self.codec.params
        return float(periods), float(p.min_fringe_period_px), float(p.max_unwrap_disagreement)

    def finest_level(self, periods: int, steps: Steps, texture: np.ndarray) -> Correspondence:
        """add_level_steps for the finest level and then `correspondence`, in one compiled pass
        (rig.kernels.radial.radial_finish)."""
        codec, p, lit = self.codec, self.codec.params, self.lit
        shape = lit.shape
        u, v, quality = (np.empty(shape, np.float32) for _ in range(3))
        radius, theta, valid = np.empty(shape, np.float32), np.empty(shape, np.float32), np.empty(shape, bool)
        extent = (codec.width, codec.height)
        constants = (self._level(periods), np.float32(p.min_modulation), tuple(map(float, codec.center)), extent)
        images = (self.gray_strong, self.consistent, self.radial_mod, self.angular_mod, self.radius, self.theta)
        outputs = (u, v, valid, quality, radius, theta)
        parts: list[tuple[int, ...]] = []
        in_row_strips(
            shape[0],
            lambda rows: parts.append(
                radial_kernels.radial_finish(*steps, *constants, lit, *images, *outputs, rows.start, rows.stop)
            ),
        )
        lit_count, low_radial, low_angular, inconsistent, decoded = (sum(column) for column in zip(*parts, strict=True))
        counts = {
            "lit": lit_count,
            "low_radial_modulation": low_radial,
            "low_angular_modulation": low_angular,
            "inconsistent_angle_levels": inconsistent,
            "decoded": decoded,
        }
        extra = {"radius": radius, "theta": theta}
        return Correspondence(valid=valid, quality=quality, texture=texture, u=u, v=v, extra=extra, counts=counts)

    def correspondence(self, texture: np.ndarray) -> Correspondence:
        codec, p, lit = self.codec, self.codec.params, self.lit
        radial_mod, angular_mod, radius, theta = self.radial_mod, self.angular_mod, self.radius, self.theta
        ok = lit & (radial_mod >= p.min_modulation) & (angular_mod >= p.min_modulation)
        ok &= self.gray_strong & (radius > 0) & self.consistent
        cu, cv = codec.center
        u = (cu + radius * np.cos(theta)).astype(np.float32)
        v = (cv + radius * np.sin(theta)).astype(np.float32)
        ok &= (u > -0.5) & (u < codec.width - 0.5) & (v > -0.5) & (v < codec.height - 0.5)
        for coord in (u, v):
            coord[~ok] = np.nan
        counts = {
            "lit": int(lit.sum()),
            "low_radial_modulation": int((lit & (radial_mod < p.min_modulation)).sum()),
            "low_angular_modulation": int((lit & (angular_mod < p.min_modulation)).sum()),
            "inconsistent_angle_levels": int((lit & ~self.consistent).sum()),
            "decoded": int(ok.sum()),
        }
        return Correspondence(
            valid=ok,
            quality=np.minimum(radial_mod, angular_mod),
            texture=texture,
            u=u,
            v=v,
            extra={"radius": radius.astype(np.float32), "theta": np.mod(theta, 2 * np.pi).astype(np.float32)},
            counts=counts,
        )


class RadialStream(FrameStream):
    """The radial decoder fed frame by frame: each level's steps are held until its last one arrives
    and are then read in one compiled pass (rig.kernels.radial), the Gray code read pair by pair in
    integer counts (GrayBits); the finest level's pass also makes the coordinates, after the last
    frame. The steps are summed in integer counts and the phase is a polynomial atan2 (as the phase
    stream's), so coordinates agree with the batch decoder's within float rounding."""

    codec: RadialCodec

    def __init__(self, codec: RadialCodec, full_scale: int) -> None:
        super().__init__(codec, full_scale)
        p = codec.params
        self._base = DenseBase(codec, full_scale, keep_contrast=False)
        self._levels = list(codec._angular_levels())
        self._min_strength = least_counts(p.white_threshold, full_scale)
        self._reader = GrayBits(codec._gray_bits())
        self._decoding: RadialDecoding | None = None
        self._held: list[np.ndarray] = []  # the current level's steps, until its last one

    def _steps(self) -> Steps:
        steps, self._held = tuple(self._held), []
        return steps, *step_weights(len(steps), self.full_scale)

    def _consume(self, index: int, frame: np.ndarray) -> None:
        image = self._base.coded_frame(index, frame)
        if image is None:
            return
        if self._decoding is None and len(self._held) == self.codec.params.steps:  # the radial phase's Gray code
            if self._reader.take(image):
                lit, reader = self._base.lit, self._reader
                assert lit is not None
                half = reader.value().astype(np.int32)  # as the batch decoder reads it
                strong = reader.strength() >= self._min_strength
                self._decoding = RadialDecoding.from_steps(self.codec, lit, self._steps(), half, strong)
            return
        self._held.append(np.ascontiguousarray(image))
        periods, steps = self._levels[0]
        if self._decoding is not None and len(self._held) == steps and len(self._levels) > 1:
            self._decoding.add_level_steps(periods, self._steps())
            self._levels.pop(0)

    def _finish(self) -> Correspondence:
        decoding, texture = self._decoding, self._base.texture
        assert decoding is not None and texture is not None and len(self._levels) == 1
        return decoding.finest_level(self._levels[0][0], self._steps(), texture)
