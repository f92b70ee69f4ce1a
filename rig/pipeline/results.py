"""What a scan produced, as data: each (projector, camera) pair's correspondence, points, ring
samples and surface (PairResult), and the scan's cloud, merge, mesh and records (ScanResult). The
orchestrator (rig.pipeline.scan) makes them; the store, the evaluation and realignment read them
without depending on how a scan runs."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rig.patterns import Correspondence
from rig.pipeline.mask_skew import MaskSkew
from rig.pipeline.mesh import Mesh
from rig.pipeline.pointset import PointSet
from rig.pipeline.ring_triangulation import RingPoints
from rig.pipeline.surface import RingSurface


@dataclass(eq=False)
class PairResult:
    """What one (projector, camera) pair produced."""

    projector: int
    camera: int
    correspondence: Correspondence
    stored_grid: np.ndarray | None  # (H, W, 3) organised points, NaN where none; None: from `points` (grid)
    points: PointSet
    rings: RingPoints | None = None  # sparse ring codecs: every triangulated sample, with diagnostics
    counts: dict[str, int] = field(default_factory=dict)
    ring_coverage: dict[str, object] | None = None  # sparse ring codecs: rig.pipeline.ring_triangulation.ring_coverage
    surface: RingSurface | None = None  # sparse ring codecs: the surface interpolated between the rings

    @property
    def grid(self) -> np.ndarray:
        """Organised points (H, W, 3) float64, NaN where none. A dense pair of the fast path keeps
        only its PointSet (one point per pixel, by `pixel`) and builds this when asked, so that a
        scan does not hold its points twice."""
        if self.stored_grid is not None:
            return self.stored_grid
        grid = np.full((*self.correspondence.valid.shape, 3), np.nan)
        grid.reshape(-1, 3)[self.points.pixel] = self.points.points
        return grid


@dataclass(eq=False)
class ScanResult:
    codec: str
    codec_params: dict[str, object]
    pairs: list[PairResult]
    cloud: PointSet
    frames_projected: int
    bytes_captured: int
    timings_ms: dict[str, float] = field(default_factory=dict)
    frames: dict[tuple[int, int], list[np.ndarray]] = field(default_factory=dict)
    merge: dict[str, object] | None = None  # the merge report, when several pairs were merged
    merged_index: np.ndarray | None = None  # indices of the kept points in the pairs' points, concatenated
    overlap: dict[int, np.ndarray] = field(default_factory=dict)  # per camera: pixels lit by several projectors
    mesh: Mesh | None = None  # ring scans with a surface: every pair's interpolated surface, meshed
    adaptive: dict[str, object] | None = None  # an adaptive scan: its ring plan and pattern economy
    exposure: dict[str, object] | None = None  # auto-exposure or HDR: the exposures and what chose them
    images: dict[str, np.ndarray] = field(default_factory=dict)  # name -> RGB image stored as <name>.png
    descriptions: dict[int, dict[str, object]] = field(default_factory=dict)  # kept frames: projector -> spec
    warnings: list[str] = field(default_factory=list)  # what the operator should know of this result
    # adaptive projection: per (projector, camera), per pass's masks, what takes their lean off a decode
    mask_skews: dict[tuple[int, int], list[MaskSkew]] = field(default_factory=dict)
