"""How a rig scans: the codec and its parameters, filters, and merging several pairs."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from rig.config.common import Strict
from rig.patterns import codec_names
from rig.patterns.gray import GrayParams
from rig.patterns.phase import PhaseParams
from rig.patterns.radial import RadialParams
from rig.patterns.rings import RingsParams


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


class ScanConfig(Strict):
    codec: str = "phase"
    gray: GrayParams = GrayParams()
    phase: PhaseParams = PhaseParams()
    rings: RingsParams = RingsParams()
    radial: RadialParams = RadialParams()
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

    @field_validator("codec")
    @classmethod
    def _known_codec(cls, v: str) -> str:
        if v not in codec_names():
            raise ValueError(f"unknown codec {v!r}; known codecs: {', '.join(codec_names())}")
        return v
