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

import numpy as np
from pydantic import Field, field_validator

from rig.patterns.base import CodecParams, Correspondence, NormalizedFrames, PixelCoord, even_period
from rig.patterns.circular import CircularCodec
from rig.patterns.fringes import fringe_images, phase_sums
from rig.patterns.graycode import bit_count, decode_gray, gray_planes, planes_with_inverses
from rig.patterns.registry import register


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


def _phase(frames: NormalizedFrames, first: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Wrapped phase in [0, 2 pi) and modulation of `steps` frames from index `first`."""
    s, c = phase_sums(frames, first, steps)
    return np.mod(np.arctan2(s, c), 2 * np.pi), (2.0 / steps) * np.sqrt(s * s + c * c)


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

    def _gray_bits(self) -> int:
        return bit_count(math.ceil((self.reach + 1) / (self.params.period_px // 2)))

    def _angular_levels(self) -> list[tuple[int, int]]:
        p = self.params
        return [(1, p.coarse_steps), (p.mid_periods, p.coarse_steps), (p.angle_periods, p.angle_steps)]

    def _coded_frame_count(self) -> int:
        return self.params.steps + 2 * self._gray_bits() + sum(steps for _, steps in self._angular_levels())

    def _coded_patterns(self) -> list[np.ndarray]:
        p = self.params
        rho, theta = self.polar()

        out = fringe_images(2 * np.pi * rho / p.period_px, p.steps)
        out += planes_with_inverses(gray_planes(np.floor(rho / (p.period_px // 2)).astype(np.int64), self._gray_bits()))
        for periods, steps in self._angular_levels():
            out += fringe_images(periods * theta, steps)
        return out

    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        p = self.params
        phi, radial_mod = _phase(frames, 0, p.steps)
        bits = self._gray_bits()
        first = p.steps
        half, strength = decode_gray(frames[first : first + 2 * bits], bits)
        first += 2 * bits
        k1, k2 = half >> 1, (half + 1) >> 1
        k = np.where(phi < np.pi / 2, k2, np.where(phi > 1.5 * np.pi, k2 - 1, k1))
        radius = (k + phi / (2 * np.pi)) * p.period_px
        theta = np.zeros(lit.shape, dtype=np.float64)
        consistent = np.ones(lit.shape, dtype=bool)
        angular_mod = np.full(lit.shape, np.inf, dtype=np.float32)
        for level, (periods, steps) in enumerate(self._angular_levels()):
            wrapped, modulation = _phase(frames, first, steps)
            first += steps
            if level == 0:
                theta, angular_mod = wrapped.astype(np.float64), modulation
                continue
            usable = 2 * np.pi * radius / periods >= p.min_fringe_period_px
            refined, disagreement = _unwrap(wrapped, theta * periods)
            theta = np.where(usable, refined / periods, theta)
            angular_mod = np.where(usable, np.minimum(angular_mod, modulation), angular_mod)
            consistent &= ~usable | (disagreement <= p.max_unwrap_disagreement)
        ok = lit & (radial_mod >= p.min_modulation) & (angular_mod >= p.min_modulation)
        ok &= (strength >= p.white_threshold) & (radius > 0) & consistent
        cu, cv = self.center
        u = (cu + radius * np.cos(theta)).astype(np.float32)
        v = (cv + radius * np.sin(theta)).astype(np.float32)
        ok &= (u > -0.5) & (u < self.width - 0.5) & (v > -0.5) & (v < self.height - 0.5)
        for coord in (u, v):
            coord[~ok] = np.nan
        counts = {
            "lit": int(lit.sum()),
            "low_radial_modulation": int((lit & (radial_mod < p.min_modulation)).sum()),
            "low_angular_modulation": int((lit & (angular_mod < p.min_modulation)).sum()),
            "inconsistent_angle_levels": int((lit & ~consistent).sum()),
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
