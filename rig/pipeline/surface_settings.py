"""The ring surface's settings (rig.pipeline.surface, rig.pipeline.ring_faces): which triangles are
kept, which pixels agree with their bands, and the fill."""

from __future__ import annotations

from dataclasses import dataclass, field

from rig.pipeline.fill import FillSettings


@dataclass(frozen=True)
class SurfaceSettings:
    max_gap_px: float = 6.0  # two samples of one ring further apart than this are not neighbours
    max_slant_deg: float = 84.0  # triangles seen more edge-on than this span a depth edge
    max_bend_deg: float = 50.0  # ... as do triangles this far from one of their corners' normals
    max_bend_excess_deg: float = 20.0  # ... and those bent this much more from their corners than they differ
    min_foreshortening: float = 0.15  # ... and edges steep to both devices (rig.pipeline.flanks) ...
    max_flank_turn_deg: float = 10.0  # ... unless they continue the surface beside them (rig.pipeline.flanks)
    max_unlit: float = 0.02  # triangles over more of their pixels dark than this span a shadow
    band_margin_px: float = 2.0  # a point may project this far outside the annulus its pixel read ...
    band_angle_rad: float = 0.15  # ... and this far from the polar angle it read (3x the code's p99.9)
    normal_smoothing_px: float = 4.0  # samples' normals averaged over their ring this far either way
    max_band_disagreement: float = 0.25  # a triangle with more of its pixels off their bands bridges an edge
    fill: bool = True  # fill the inner disc and holes the rings enclose (rig.pipeline.fill)
    fill_settings: FillSettings = field(default_factory=FillSettings)
