"""`rings`: sparse concentric rings, as in Lee's dissertation, made robust.

Frames after white and black:
- the edge pattern E and its inverse: annulus a (between rings a-1 and a; annulus 0 is the disc
  inside ring 0) is lit when a is odd, so E - inverse changes sign exactly on every ring. Ring edges
  are anti-aliased by the pixel's signed distance to the circle, so the zero crossing is the circle
  itself at sub-pixel precision, and (pattern and inverse being symmetric) whatever the projector's
  gamma.
- the ring index, Gray-coded with inverses over zones centred on the rings (zone k runs from midway
  to ring k-1 to midway to ring k+1): at a ring point both neighbouring pixels lie well inside zone
  k, so the index is read far from any edge of its own code. No ring counting, so occlusions do not
  shift the numbering.
- a coarse angular code: one period of a cosine in the polar angle, `angle_steps` shifts. It only has
  to choose between the two points where a camera ray meets a ring's cone.

A ring point is where E - inverse changes sign between two lit, horizontally or vertically adjacent
camera pixels that read the same ring index: its position is the linear zero crossing.
"""

from __future__ import annotations

import functools
import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from rig.patterns.base import CodecParams, Correspondence, NormalizedFrames, PixelCoord, RingSamples
from rig.patterns.circular import CircularCodec
from rig.patterns.graycode import bit_count, decode_gray, gray_planes, planes_with_inverses
from rig.patterns.registry import register

# Width of the anti-aliased ramp across a ring edge: wide enough that both camera pixels around a
# zero crossing sit on the straight part of the ramp, so linear interpolation finds the circle.
_EDGE_RAMP_PX = 2.0


class RingsParams(CodecParams):
    rings: int = Field(32, ge=1, le=1024, description="number of rings K")
    first_radius_px: float = Field(16.0, gt=0, le=16384, description="radius of the innermost ring")
    spacing_px: float | None = Field(
        None,
        gt=2 * _EDGE_RAMP_PX,
        le=16384,
        description="ring spacing; default: the K rings reach the farthest image corner",
    )
    radii_px: list[Annotated[float, Field(gt=0, le=1e5)]] | None = Field(
        None, max_length=1024, description="explicit radii, increasing (instead of rings/first_radius_px/spacing_px)"
    )
    center_px: tuple[PixelCoord, PixelCoord] | None = Field(None, description="ring centre; default: the image centre")
    angle_steps: int = Field(4, ge=3, le=32, description="phase steps of the angular code")
    min_edge_contrast: float = Field(
        0.03, ge=0.0, le=2.0, description="minimum |step| of pattern - inverse across a ring edge"
    )
    min_cos_beta: float = Field(
        0.3,
        ge=0.0,
        le=1.0,
        description="mask points where |cos| of the angle between the ring's radial direction and the "
        "epipolar line is below this: there a radius error moves the point by 1/|cos| times more",
    )
    min_radius_px: float = Field(8.0, ge=0.0, le=16384, description="mask rings smaller than this")
    model: Literal["cone", "parallel", "radius_ratio"] = Field(
        "cone",
        description="cone: calibrated ray-cone intersection (any layout); parallel: the dissertation's ch.2 "
        "closed form (orthographic projector and camera); radius_ratio: its ch.7 model (orthographic "
        "projector, pinhole camera on the rings' axis)",
    )
    radius_sigma_px: float = Field(
        0.05, gt=0, le=10, description="assumed ring localisation error, for the per-point uncertainty"
    )

    @model_validator(mode="after")
    def _radii_increase(self) -> RingsParams:
        if self.radii_px is not None:
            r = np.asarray(self.radii_px)
            if len(r) == 0 or np.any(r <= 0) or np.any(np.diff(r) <= 2 * _EDGE_RAMP_PX):
                raise ValueError(f"radii_px must be positive and increase by more than {2 * _EDGE_RAMP_PX:g} px")
            if "rings" in self.model_fields_set and self.rings != len(r):
                raise ValueError(f"rings is {self.rings} but radii_px lists {len(r)} radii; give one of them")
        return self


@register
class RingsCodec(CircularCodec):
    name = "rings"
    Params = RingsParams
    params: RingsParams

    def __init__(
        self, projector_size: tuple[int, int], params: RingsParams | None = None, output_lut: np.ndarray | None = None
    ) -> None:
        super().__init__(projector_size, params, output_lut)
        steps = np.diff(self.radii)
        if self.radii[0] <= 0 or (steps <= 2 * _EDGE_RAMP_PX).any():
            raise ValueError(
                f"rings: radii {self.radii[0]:.1f}..{self.radii[-1]:.1f} px must be positive and at least "
                f"{2 * _EDGE_RAMP_PX:g} px apart in a {self.width}x{self.height} projector image "
                "(fewer rings, a smaller first_radius_px or an explicit spacing_px)"
            )

    @functools.cached_property
    def radii(self) -> np.ndarray:
        """Ring radii in projector pixels; `radii_px` when given, else `rings` evenly spaced."""
        p = self.params
        if p.radii_px is not None:
            return np.asarray(p.radii_px, dtype=np.float64)
        if p.spacing_px is not None:
            spacing = p.spacing_px
        else:
            spacing = (self.reach - p.first_radius_px) / max(1, p.rings - 1) if p.rings > 1 else 1.0
        return p.first_radius_px + spacing * np.arange(p.rings)

    def _zone(self, rho: np.ndarray) -> np.ndarray:
        radii = self.radii
        midpoints = 0.5 * (radii[1:] + radii[:-1])
        return np.searchsorted(midpoints, rho, side="right")

    def _zone_bits(self) -> int:
        return bit_count(max(2, len(self.radii)))

    def _coded_frame_count(self) -> int:
        return 2 + 2 * self._zone_bits() + self.params.angle_steps

    def _coded_patterns(self) -> list[np.ndarray]:
        rho, theta = self.polar()
        radii = self.radii
        nearest = np.clip(np.searchsorted(radii, rho), 1, len(radii) - 1) if len(radii) > 1 else np.zeros_like(rho, int)
        if len(radii) > 1:
            nearest = np.where(np.abs(rho - radii[nearest - 1]) < np.abs(rho - radii[nearest]), nearest - 1, nearest)
        signed = rho - radii[nearest]  # > 0 outside the nearest ring
        outside_lit = (nearest % 2) == 0  # outside ring k is annulus k + 1: lit when k + 1 is odd
        ramp = np.where(outside_lit, signed, -signed) / _EDGE_RAMP_PX
        coverage = np.clip(0.5 + ramp, 0.0, 1.0)
        edge = np.rint(coverage * 255).astype(np.uint8)
        out = [edge, 255 - edge]
        out += planes_with_inverses(gray_planes(self._zone(rho), self._zone_bits()))
        steps = self.params.angle_steps
        for n in range(steps):
            value = 0.5 + 0.5 * np.cos(theta - 2 * np.pi * n / steps)
            out.append(np.rint(value * 255).astype(np.uint8))
        return out

    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        p = self.params
        edge = frames[0] - frames[1]
        bits = self._zone_bits()
        zone, strength = decode_gray(frames[2 : 2 + 2 * bits], bits)
        zone_ok = lit & (strength >= p.min_edge_contrast * 0.5) & (zone < len(self.radii))
        s = np.zeros(lit.shape, dtype=np.float32)
        c = np.zeros(lit.shape, dtype=np.float32)
        for n in range(p.angle_steps):
            delta = 2 * np.pi * n / p.angle_steps
            frame = frames[2 + 2 * bits + n]
            s += frame * np.float32(math.sin(delta))
            c += frame * np.float32(math.cos(delta))
        gy, gx = np.gradient(edge)
        steep = np.abs(gy) >= np.abs(gx)  # the edge crosses columns more than rows
        xy, ring, theta, contrast = [], [], [], []
        for axis in (0, 1):  # crossings between vertical, then horizontal neighbours
            a = (slice(None, -1), slice(None)) if axis == 0 else (slice(None), slice(None, -1))
            b = (slice(1, None), slice(None)) if axis == 0 else (slice(None), slice(1, None))
            d1, d2 = edge[a], edge[b]
            step = d1 - d2
            # A sign change, counting 0 as positive: a pixel exactly on the ring (common in 8-bit
            # captures) still yields its crossing, and each crossing is found once.
            found = ((d1 >= 0) != (d2 >= 0)) & zone_ok[a] & zone_ok[b] & (zone[a] == zone[b])
            found &= np.abs(step) >= p.min_edge_contrast
            # Search across the edge, not along it: each point once, from the better-conditioned pair.
            found &= steep[a] if axis == 0 else ~steep[a]
            rows, cols = np.nonzero(found)
            t = d1[rows, cols] / step[rows, cols]  # fraction of the way from pixel a to pixel b
            x = cols + (t if axis == 1 else 0.0)
            y = rows + (t if axis == 0 else 0.0)
            bi = (rows + (axis == 0), cols + (axis == 1))
            si = (1 - t) * s[rows, cols] + t * s[bi]
            ci = (1 - t) * c[rows, cols] + t * c[bi]
            xy.append(np.column_stack([x, y]))
            ring.append(zone[rows, cols])
            theta.append(np.arctan2(si, ci))
            contrast.append(np.abs(step[rows, cols]))
        samples_xy = np.concatenate(xy).astype(np.float64)
        ring_idx = np.concatenate(ring).astype(np.int64)
        samples = RingSamples(
            camera_xy=samples_xy,
            ring=ring_idx,
            radius_px=self.radii[ring_idx],
            theta=np.concatenate(theta).astype(np.float64),
            contrast=np.concatenate(contrast).astype(np.float32),
            center_px=self.center,
            min_cos_beta=p.min_cos_beta,
            min_radius_px=p.min_radius_px,
            radius_sigma_px=p.radius_sigma_px,
            model=p.model,
        )
        valid = np.zeros(lit.shape, dtype=bool)
        nearest = np.rint(samples_xy).astype(np.int64)
        valid[nearest[:, 1], nearest[:, 0]] = True
        counts = {"lit": int(lit.sum()), "ring_samples": len(samples), "rings_seen": len(np.unique(ring_idx))}
        return Correspondence(valid=valid, quality=white - black, texture=texture, samples=samples, counts=counts)
