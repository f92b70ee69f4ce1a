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
- a coarse angular code: one period of a cosine in the polar angle, `angle_steps` shifts. It
  chooses between the two points where a camera ray meets a ring's cone.
- a fine angular code (unless `tangential_period_px` is None): in zone k, M_k periods of a cosine in
  the polar angle, M_k chosen so that a period along ring k is about `tangential_period_px`,
  `tangential_steps` shifts. Where a ring runs along the epipolar line its radius says little about
  depth; there this tangential coordinate does (rig.pipeline.ring_angles).

A ring point is where E - inverse changes sign between two lit, horizontally or vertically adjacent
camera pixels that read the same ring index: its position is the linear zero crossing.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from rig.lazy import lazy_module
from rig.patterns.base import CodecParams, PixelCoord
from rig.patterns.circular import CircularCodec
from rig.patterns.correspondence import Correspondence, NormalizedFrames, RingSamples
from rig.patterns.crossings import Crossings, LocatedRings
from rig.patterns.fringes import PATTERN_ROWS, PointSums, fringe_images, phase_sums
from rig.patterns.graycode import bit_count, decode_gray, gray_images
from rig.patterns.registry import register
from rig.patterns.rings_stream import RingsStream
from rig.patterns.stream import FrameStream
from rig.workers import in_row_strips, point_blocks

ring_kernels = lazy_module("rig.kernels.rings")  # numba compiles on first use: not for --help

# A crossing whose step is more than this many times the scan's median is a jump, not a ramp.
_RAMP_MEDIAN_FACTOR = 1.5

# Width of the anti-aliased ramp across a ring edge: wide enough that both camera pixels around a
# zero crossing sit on the straight part of the ramp, so linear interpolation finds the circle.
EDGE_RAMP_PX = 2.0
# The coarse angle code's typical error (radians; its 99.9th percentile over a scan is 0.05).
_ANGLE_SLACK_RAD = 0.01


class RingsParams(CodecParams):
    rings: int = Field(32, ge=1, le=1024, description="number of rings K")
    first_radius_px: float = Field(16.0, gt=0, le=16384, description="radius of the innermost ring")
    spacing_px: float | None = Field(
        None,
        gt=2 * EDGE_RAMP_PX,
        le=16384,
        description="ring spacing; default: the K rings reach the farthest image corner",
    )
    radii_px: list[Annotated[float, Field(gt=0, le=1e5)]] | None = Field(
        None, max_length=1024, description="explicit radii, increasing (instead of rings/first_radius_px/spacing_px)"
    )
    center_px: tuple[PixelCoord, PixelCoord] | None = Field(None, description="ring centre; default: the image centre")
    angle_steps: int = Field(4, ge=3, le=32, description="phase steps of the angular code")
    tangential_period_px: float | None = Field(
        16.0,
        ge=4.0,
        le=4096.0,
        description="period of the fine angular code along each ring, projector pixels (projected for the cone "
        "model only); None: no fine code, and the samples where the ring runs along the epipolar line are "
        "masked (min_cos_beta)",
    )
    tangential_steps: int = Field(4, ge=3, le=32, description="phase steps of the fine angular code")
    tangential_sigma_px: float = Field(
        0.1, gt=0, le=10, description="assumed error of the fine angular code along the ring, projector pixels"
    )
    min_edge_contrast: float = Field(
        0.03, ge=0.0, le=2.0, description="minimum |step| of pattern - inverse across a ring edge"
    )
    min_cos_beta: float = Field(
        0.3,
        ge=0.0,
        le=1.0,
        description="without the fine angular code, mask points where |cos| of the angle between the ring's "
        "radial direction and the epipolar line is below this: there a radius error moves the point by "
        "1/|cos| times more",
    )
    max_edge_step: float = Field(
        0.5,
        gt=0.0,
        le=1.0,
        description="a ring edge rises over 2 px of the projector image, so between two neighbouring camera "
        "pixels pattern - inverse (as a fraction of white - black) steps by about the projector pixels one "
        "camera pixel spans, halved; a larger half-step is a depth edge jumping across an annulus, not a ring. "
        "Crossings stepping more than this (or 1.5 times the scan's median, when the camera is coarser) are dropped",
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
            if len(r) == 0 or np.any(r <= 0) or np.any(np.diff(r) <= 2 * EDGE_RAMP_PX):
                raise ValueError(f"radii_px must be positive and increase by more than {2 * EDGE_RAMP_PX:g} px")
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
        if self.radii[0] <= 0 or (steps <= 2 * EDGE_RAMP_PX).any():
            raise ValueError(
                f"rings: radii {self.radii[0]:.1f}..{self.radii[-1]:.1f} px must be positive and at least "
                f"{2 * EDGE_RAMP_PX:g} px apart in a {self.width}x{self.height} projector image "
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

    @functools.cached_property
    def fine_periods(self) -> np.ndarray | None:
        """Periods per revolution of the fine angular code in each ring's zone (None: no fine code)."""
        period = self.params.tangential_period_px
        if period is None or self.params.model != "cone":  # the closed-form models read the radius only
            return None
        return np.maximum(1, np.rint(2 * np.pi * self.radii / period)).astype(np.int64)

    def _zone_bits(self) -> int:
        return bit_count(max(2, len(self.radii)))

    def _fine_steps(self) -> int:
        return 0 if self.fine_periods is None else self.params.tangential_steps

    def _coded_frame_count(self) -> int:
        return 2 + 2 * self._zone_bits() + self.params.angle_steps + self._fine_steps()

    def _coded_iter(self) -> Iterator[np.ndarray]:
        """The coded patterns one at a time, each made as its turn comes: between them the polar angle
        and the ring zones are held, not the sequence (all twenty at once and their float
        temporaries were 75 MB of a scan's peak on the default bench)."""
        rho = self.radius()
        edge, zone = self._edge_and_zones(rho)
        del rho
        yield edge
        yield 255 - edge
        del edge
        yield from gray_images(zone, self._zone_bits())
        theta = self.angle()
        yield from fringe_images(theta, self.params.angle_steps)
        if self.fine_periods is not None:
            yield from fringe_images(self.fine_periods[zone] * theta, self.params.tangential_steps)

    def _edge_and_zones(self, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At projector radii `rho`: the edge pattern E (uint8), each pixel lit by the share of it on
        the lit side of its nearest ring (its signed distance over EDGE_RAMP_PX), and each pixel's
        ring zone (int32), a band of rows at a time."""
        radii, edge, zone = self.radii, np.empty(rho.shape, np.uint8), np.empty(rho.shape, np.int32)
        for rows in point_blocks(len(rho), PATTERN_ROWS):
            part = rho[rows]
            zone[rows] = self._zone(part)
            if len(radii) > 1:
                above = np.clip(np.searchsorted(radii, part), 1, len(radii) - 1)
                nearest = np.where(np.abs(part - radii[above - 1]) < np.abs(part - radii[above]), above - 1, above)
            else:
                nearest = np.zeros_like(part, int)
            signed = part - radii[nearest]  # > 0 outside the nearest ring
            outside_lit = (nearest % 2) == 0  # outside ring k is annulus k + 1: lit when k + 1 is odd
            ramp = np.where(outside_lit, signed, -signed) / EDGE_RAMP_PX
            edge[rows] = np.rint(np.clip(0.5 + ramp, 0.0, 1.0) * 255)
        return edge, zone

    def _decode(
        self, frames: NormalizedFrames, white: np.ndarray, black: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        p = self.params
        edge = frames[0] - frames[1]
        candidates = Crossings.candidates(edge, p.min_edge_contrast)
        bits = self._zone_bits()
        zone, strength = decode_gray(frames[2 : 2 + 2 * bits], bits)
        first = 2 + 2 * bits
        coarse = phase_sums(frames, first, p.angle_steps)  # at the crossings, and everywhere for _bands
        contrast = white - black
        found = self.locate(candidates, edge, contrast, zone, strength >= p.min_edge_contrast * 0.5, lit, coarse)
        fine = None
        if self.fine_periods is not None:
            fine = PointSums(found.ends, p.tangential_steps)
            for n in range(p.tangential_steps):
                fine.add(frames[first + p.angle_steps + n][fine.pixels])
        return self.correspondence(found, fine, contrast, lit, texture)

    def locate(
        self,
        candidates: Crossings,
        edge: np.ndarray,
        contrast: np.ndarray,
        zone: np.ndarray,
        zone_strong: np.ndarray,
        lit: np.ndarray,
        coarse: tuple[np.ndarray, np.ndarray],
    ) -> LocatedRings:
        """The ring points among the edge pattern's sign changes, once the ring index (`zone`, read
        strongly enough where `zone_strong`) and the coarse angle's sums are known."""
        p = self.params
        zone_ok = lit & zone_strong & (zone < len(self.radii))
        found = candidates.within_zones(zone, zone_ok)
        # A ring edge is a ramp; a depth edge across an annulus is a jump (see max_edge_step).
        ramp = found.ramp(edge, contrast)
        limit = max(p.max_edge_step, _RAMP_MEDIAN_FACTOR * float(np.median(ramp))) if len(ramp) else 1.0
        crossings = found.select(ramp <= limit)
        assert crossings.ring is not None
        theta = np.arctan2(*crossings.between(*coarse))
        on_frame = self._on_frame(crossings.ring, theta)
        return LocatedRings(
            crossings=crossings.select(on_frame),
            theta=theta[on_frame].astype(np.float64),
            counts={"rejected_edge_jump": int((ramp > limit).sum()), "rejected_off_frame": int((~on_frame).sum())},
            bands=self._bands(edge, zone, zone_ok, coarse, lit),
        )

    def correspondence(
        self, found: LocatedRings, fine: PointSums | None, contrast: np.ndarray, lit: np.ndarray, texture: np.ndarray
    ) -> Correspondence:
        """The ring points as samples, with the fine angle's phase where the fine code was read
        (its sums at each crossing's two pixels)."""
        p, crossings = self.params, found.crossings
        assert crossings.ring is not None
        xy = crossings.xy  # computed on each ask
        phase, periods = None, None
        if fine is not None:
            fs, fc = crossings.interpolate(*fine.at_ends())
            phase = np.arctan2(fs, fc).astype(np.float64)
            phase[(2.0 / p.tangential_steps) * np.hypot(fs, fc) < p.min_edge_contrast] = np.nan  # unreadable
            periods = self.fine_periods[crossings.ring] if self.fine_periods is not None else None
        samples = RingSamples(
            camera_xy=xy,
            ring=crossings.ring,
            radius_px=self.radii[crossings.ring],
            theta=found.theta,
            contrast=np.abs(crossings.step).astype(np.float32),
            center_px=self.center,
            ring_radii_px=self.radii,
            min_cos_beta=p.min_cos_beta,
            min_radius_px=p.min_radius_px,
            radius_sigma_px=p.radius_sigma_px,
            model=p.model,
            fine_phase=phase,
            fine_periods=periods,
            tangential_sigma_px=p.tangential_sigma_px,
            shown_within_px=self._shown_within(),
        )
        valid = np.zeros(lit.shape, dtype=bool)
        nearest = np.rint(xy).astype(np.int64)
        valid[nearest[:, 1], nearest[:, 0]] = True
        counts = {
            "lit": int(np.count_nonzero(lit)),  # a tenth of sum's time
            "ring_samples": len(samples),
            "rings_seen": int(np.count_nonzero(np.bincount(crossings.ring))),  # not a sort, as np.unique
            **found.counts,
        }
        if phase is not None:
            counts["no_fine_angle"] = int(np.isnan(phase).sum())
        return Correspondence(
            valid=valid, quality=contrast, texture=texture, samples=samples, counts=counts, extra=found.bands
        )

    def stream(self, full_scale: int) -> FrameStream:
        return RingsStream(self, full_scale)

    def _on_frame(self, ring: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Whether each ring's edge is shown whole (_shown_within) at the polar angle read, or within
        the coarse angle's error there (_ANGLE_SLACK_RAD: a ring crossing the border steeply keeps
        its samples up to it). Where a ring runs along the border, the border cuts its ramp or hides
        it, and the edge found there is off by pixels: on the ring's cone, where it runs along the
        epipolar direction, centimetres off."""
        cu, cv = self.center
        radius = self.radii[ring]
        left, right, top, bottom = self._shown_within()
        on = np.zeros(len(ring), dtype=bool)
        for slack in (-_ANGLE_SLACK_RAD, 0.0, _ANGLE_SLACK_RAD):
            u, v = cu + radius * np.cos(theta + slack), cv + radius * np.sin(theta + slack)
            on |= (u >= left) & (u <= right) & (v >= top) & (v <= bottom)
        return on

    def _shown_within(self) -> tuple[float, float, float, float]:
        """The projector coordinates (u from, to; v from, to) where a ring's edge is shown whole and
        clear of the frame's border: its ramp spans the ring +- EDGE_RAMP_PX / 2, and a camera's
        blur of the border (a pixel or so) reaches as far again."""
        m = EDGE_RAMP_PX
        return (m, self.width - 1 - m, m, self.height - 1 - m)

    def _bands(
        self,
        edge: np.ndarray,
        zone: np.ndarray,
        zone_ok: np.ndarray,
        sums: tuple[np.ndarray, np.ndarray],
        lit: np.ndarray,
    ) -> dict[str, np.ndarray]:
        """Where every pixel lies in the projector image, coarsely: `annulus` a (between rings a-1
        and a; -1 unread), from its zone and the edge pattern's parity, and `angle`, the coarse polar
        angle (NaN unread). The surface between the rings checks its points against them. One
        compiled pass over row strips (rig.kernels.rings.ring_bands)."""
        p = self.params
        annulus, angle = np.empty(edge.shape, np.int16), np.empty(edge.shape, np.float32)
        read, thresholds = (edge, zone, zone_ok, lit), (float(p.min_edge_contrast), 2.0 / p.angle_steps)
        in_row_strips(
            edge.shape[0],
            lambda rows: ring_kernels.ring_bands(read, sums, thresholds, annulus, angle, rows.start, rows.stop),
        )
        return {"annulus": annulus, "angle": angle}
