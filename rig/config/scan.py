"""How a rig scans: the codec and its parameters, filters, and merging several pairs."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from rig.config.common import Strict
from rig.patterns import (
    CodecParams,
    CuedPhaseParams,
    GrayParams,
    PhaseParams,
    RadialParams,
    RingsParams,
    codec_class,
    codec_names,
)

LIVE_PHASE_STEPS = 4


def _known_codec_name(name: str) -> str:
    if name not in codec_names():
        raise ValueError(f"unknown codec {name!r}; known codecs: {', '.join(codec_names())}")
    return name


class MergeConfig(Strict):
    """How the clouds of several (projector, camera) pairs become one (rigs with more than one pair)."""

    enabled: bool = True
    radius_mm: float | None = Field(
        None,
        gt=0,
        le=50,
        description="a point goes if a better one of another pair is this close; null: twice the sampling distance",
    )
    voxel_mm: float | None = Field(
        None, ge=0, le=50, description="thinning grid; null: the coarsest pair's sampling distance; 0: no thinning"
    )
    overlap_cue: bool = Field(True, description="capture dark, each projector white, all white: finds the overlap")
    cue_ratio: float = Field(0.08, gt=0, lt=1, description="overlap: light beyond the brightest projector's share")
    refine: Literal["none", "icp"] = Field("none", description="icp: realign every pair to the first by ICP")
    icp_max_distance_mm: float = Field(5.0, gt=0, le=100, description="ICP correspondences farther apart are ignored")
    pairs: list[tuple[int, int]] | None = Field(
        None, min_length=1, max_length=256, description="the (projector, camera) pairs to reconstruct; null: all"
    )


class SurfaceConfig(Strict):
    """The dense surface between the rings of a ring scan (rig.pipeline.surface)."""

    interpolate: bool = Field(True, description="ring scans: interpolate a surface between the rings (mesh.ply)")
    interpolant: Literal["linear", "quadratic", "cubic"] = Field(
        "quadratic", description="linear: the samples' triangles; quadratic: with their normals; cubic: Clough-Tocher"
    )
    mesh_stride_px: int = Field(2, ge=1, le=16, description="a mesh vertex every this many camera pixels")
    colour: Literal["white", "nearest", "idw", "area"] = Field(
        "white",
        description="the surface's colour: white: the lit frame at every pixel; nearest, idw, area: only the "
        "ring samples' colours, interpolated between the rings (rig.pipeline.colour)",
    )
    colour_neighbours: int = Field(8, ge=1, le=64, description="L: samples the colour interpolants consider per ring")
    max_gap_px: float = Field(
        6.0, gt=0.0, le=1000.0, description="samples of one ring further apart in the image are not neighbours"
    )


class RingPlanSettings(Strict):
    """How an adaptive scan plans its rings from a pilot scan (rig.plan.ring_spacing)."""

    tolerance_mm: float = Field(
        0.2,
        gt=0.0,
        le=100.0,
        description="the surface is within this of the object over tolerance_quantile of its area",
    )
    tolerance_quantile: float = Field(
        0.95, ge=0.5, le=1.0, description="the share of every surface region's area that must lie within tolerance_mm"
    )
    min_coverage: float = Field(
        0.95, ge=0.0, le=1.0, description="a plan's surface covers at least this share of the area within its rings"
    )
    pilot_codec: str = Field("phase", description="the dense codec of the pilot scan")
    curvature_radius_mm: float = Field(
        5.0, ge=0.5, le=200.0, description="smoothing scale: curvature is fitted over neighbours this close"
    )
    min_spacing_px: float = Field(6.0, gt=4.0, le=4096.0, description="rings never closer than this (projector px)")
    max_spacing_px: float = Field(
        256.0, gt=4.0, le=4096.0, description="rings never further apart: flat surface still needs its outline"
    )
    min_radius_px: float = Field(8.0, ge=0.0, le=4096.0, description="the innermost ring at least this large")
    rehearsal_step_px: int = Field(
        2, ge=1, le=16, description="the plan is rehearsed on every n-th pilot pixel row and column"
    )
    keep_coverage: float = Field(
        0.95, gt=0.0, le=1.0, description="a plan covers at least this fraction of what the densest rings cover"
    )
    rehearsal_margin: float = Field(
        0.85,
        gt=0.0,
        le=1.0,
        description="a plan rehearses within this share of the tolerance: the rehearsal, on a pilot seen at "
        "1/rehearsal_step_px of the camera's resolution, can be the more optimistic (docs/rings.md)",
    )
    bin_px: float = Field(2.0, gt=0.0, le=64.0, description="radius bins of the spacing profile")
    demand_quantile: float = Field(
        0.98, gt=0.5, le=1.0, description="each radius gets the spacing this fraction of its surface allows"
    )
    energy_fraction: float = Field(
        0.95, gt=0.5, lt=1.0, description="curvature-frequency criterion: the band limit holds this much energy"
    )
    dense_spacing_px: float = Field(
        8.0, gt=4.0, le=1024.0, description="curvature-frequency criterion: spacing of the N dense rings"
    )
    curve_step_mm: float = Field(0.5, gt=0.0, le=50.0, description="ring curves resampled at this arc length")
    curve_smooth_mm: float = Field(3.0, gt=0.0, le=100.0, description="ring curves smoothed over this arc length")
    min_curve_mm: float = Field(20.0, gt=0.0, le=10_000.0, description="shorter ring pieces are not measured")

    @field_validator("pilot_codec")
    @classmethod
    def _known_codec(cls, v: str) -> str:
        if v not in codec_names():
            raise ValueError(f"unknown codec {v!r}; known codecs: {', '.join(codec_names())}")
        return v

    @model_validator(mode="after")
    def _spacings_ordered(self) -> RingPlanSettings:
        if self.min_spacing_px > self.max_spacing_px:
            raise ValueError(f"min_spacing_px {self.min_spacing_px} exceeds max_spacing_px {self.max_spacing_px}")
        return self


class LiveConfig(Strict):
    """Live mode (`slrig live`, `/v1/live`): the short sequence the rig repeats."""

    codec: str = Field("phase", description="the codec live mode repeats")
    params: dict[str, Any] | None = Field(
        None,
        description="the codec's parameters that differ from scan.<codec>; null: 4 steps for phase, none otherwise",
    )
    hdr: Literal["auto"] | list[Annotated[float, Field(ge=1.0, le=1e7)]] | None = Field(
        None,
        description="every sequence at several exposures, merged per pixel: auto (bracketed once, from a "
        "pre-capture, when live mode starts) or 2 to 4 exposures in microseconds; null: one exposure",
    )

    _known_codec = field_validator("codec")(_known_codec_name)

    @model_validator(mode="after")
    def _exposures(self) -> LiveConfig:
        if isinstance(self.hdr, list) and not 2 <= len(self.hdr) <= 4:
            raise ValueError(f"hdr: 2 to 4 exposures in live mode, got {len(self.hdr)}")
        return self


ExposureUs = Annotated[float, Field(ge=1.0, le=1e7)]


class ExposureConfig(Strict):
    """How long the cameras expose a scan (rig.pipeline.exposure)."""

    exposure: ExposureUs | Literal["auto", "camera"] = Field(
        "camera",
        description="camera: each camera's own setting; auto: from a white and a black pre-capture, the brightest "
        "lit pixels at 85 % of full scale; a number: that many microseconds for every camera",
    )
    hdr: Annotated[int, Field(ge=2, le=10)] | Literal["auto"] | list[ExposureUs] | None = Field(
        None,
        description="capture the patterns at several exposures, merged per pixel: auto (as many as the pre-capture "
        "asks for, two stops apart), a count (that many, two stops apart from the shortest that does not clip), "
        "or the exposures in microseconds; null: one exposure",
    )
    adaptive_projection: bool = Field(
        False,
        description="dim each projector's patterns where the camera would clip (a mask from a pre-scan at a short "
        "exposure), so that one exposure long enough for the darkest lit surface reads the brightest too; "
        "with hdr, the bracket is taken with the masks (rig.pipeline.projection_mask)",
    )
    adaptive_passes: Literal["auto", 1, 2] = Field(
        "auto",
        description="adaptive projection's passes at the one exposure: 2 moves the masks' steps to either side of "
        "each edge of strong contrast, so the pixels one pass loses beside them are read by the other "
        "(rig.pipeline.mask_passes); auto: 2 where over 1 % of the lit projector pixels lie where one pass's steps "
        "would lean a decode too far to keep it",
    )
    deblur_px: float = Field(
        0.0,
        ge=0.0,
        le=0.9,
        description="the cameras' optical blur, a Gaussian's sigma in pixels: frames are deconvolved by it before "
        "they are decoded, so a dark pixel beside a bright one reads its own pattern (rig.patterns.deblur); 0: off",
    )
    drop_outshone: bool = Field(
        False,
        description="leave out every pixel beside a far brighter one (a black part on white paper): the lens's blur "
        "spills the bright side's patterns into it, and what it reads lies toward its neighbour (rig.patterns.spill)",
    )

    @model_validator(mode="after")
    def _exposures(self) -> ExposureConfig:
        if isinstance(self.hdr, list) and not 2 <= len(self.hdr) <= 10:
            raise ValueError(f"hdr: 2 to 10 exposures, got {len(self.hdr)}")
        if self.adaptive_passes == 2 and self.hdr is not None:
            raise ValueError("adaptive_passes: two passes share one exposure; with hdr, one mask serves the bracket")
        return self


class ScanConfig(Strict):
    codec: str = "phase"
    exposure: ExposureConfig = ExposureConfig()
    gray: GrayParams = GrayParams()
    phase: PhaseParams = PhaseParams()
    rings: RingsParams = RingsParams()
    radial: RadialParams = RadialParams()
    cued_phase: CuedPhaseParams = CuedPhaseParams()
    capture_timeout_s: float = Field(5.0, gt=0.0, le=120.0)
    max_depth_jump_mm: float | None = Field(
        2.0,
        gt=0.0,
        le=1000.0,
        description="dense codecs drop a point unless 3 of its 8 neighbours are within this depth of it "
        "(removes mixed pixels on depth edges and isolated decoding errors); null keeps every point",
    )
    save_frames: bool = Field(False, description="keep raw captures in the scan directory")
    merge: MergeConfig = MergeConfig()
    surface: SurfaceConfig = SurfaceConfig()
    adaptive: RingPlanSettings = RingPlanSettings()
    live: LiveConfig = LiveConfig()

    _known_codec = field_validator("codec")(_known_codec_name)

    def codec_params(self, codec: str, overrides: dict[str, Any] | None = None) -> CodecParams | None:
        """The parameters `codec` scans with (its section of this config), with `overrides`
        validated by the codec's own parameter model; None: the codec has no section here."""
        params = getattr(self, codec, None)
        if not overrides:
            return params
        base = params.model_dump() if params is not None else {}
        return codec_class(codec).Params.model_validate({**base, **overrides})

    def live_params(self) -> CodecParams | None:
        overrides = self.live.params
        if overrides is None:
            # 4 steps, not 3: an uncorrected projector gamma leaves 3 steps 0.55 mm off (median, the
            # default bench) against 0.04 mm for 4, which cancel the second harmonic; one frame more
            overrides = {"steps": LIVE_PHASE_STEPS} if self.live.codec == "phase" else {}
        return self.codec_params(self.live.codec, overrides)
