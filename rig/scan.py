"""One scan: show every pattern, capture every camera, decode, triangulate, merge."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from rig.errors import DecodeError, ScanError
from rig.patterns import Codec, Correspondence, codec_class
from rig.pointset import PointSet
from rig.progress import ProgressCallback, ProgressTracker
from rig.reconstruct import pair_pointset, reject_isolated
from rig.reconstruct_sparse import RingPoints, ring_pointset, triangulate_rings
from rig.rig import Rig
from rig.sequencer import capture


@dataclass(eq=False)
class PairResult:
    """What one (projector, camera) pair produced."""

    projector: int
    camera: int
    correspondence: Correspondence
    grid: np.ndarray  # (H, W, 3) organised points, NaN where none
    points: PointSet
    rings: RingPoints | None = None  # sparse ring codecs: every triangulated sample, with diagnostics
    counts: dict[str, int] = field(default_factory=dict)


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


def make_codec(rig: Rig, projector: int, name: str | None = None) -> Codec:
    name = name or rig.config.scan.codec
    cls = codec_class(name)
    params = getattr(rig.config.scan, name, None)
    lut = rig.response_luts[projector] if rig.response_luts else None
    return cls(tuple(rig.config.projectors[projector].resolution), params, lut)


def reconstruct_pair(
    rig: Rig, projector: int, camera: int, corr: Correspondence, source: int, elapsed: dict[str, float] | None = None
) -> PairResult:
    """Triangulate one pair's correspondence and build its PointSet; adds the seconds spent to
    `elapsed["triangulate"]` and `elapsed["pointset"]` when given."""
    t = time.perf_counter()
    model = rig.camera_models[camera]
    rings, counts = None, dict(corr.counts)
    if corr.samples is not None:
        rings, ring_counts = triangulate_rings(model, rig.projector_models[projector], corr.samples)
        counts.update(ring_counts)
    else:
        grid, valid = rig.triangulator(projector, camera).triangulate(corr)
        limit = rig.config.scan.max_depth_jump_mm
        if limit is not None:
            keep = reject_isolated(grid, valid, model, limit)
            counts["rejected_depth_jump"] = int((valid & ~keep).sum())
            grid[valid & ~keep] = np.nan
            valid = keep
    t_mid = time.perf_counter()
    if rings is not None:
        points, grid, valid = ring_pointset(rings, model, corr, source=source)
    else:
        points = pair_pointset(grid, valid, model, corr, source=source)
    counts["points"] = len(points)
    if elapsed is not None:
        elapsed["triangulate"] = elapsed.get("triangulate", 0.0) + t_mid - t
        elapsed["pointset"] = elapsed.get("pointset", 0.0) + time.perf_counter() - t_mid
    return PairResult(projector, camera, corr, grid, points, rings, counts)


def run_scan(
    rig: Rig, codec_name: str | None = None, progress: ProgressCallback | None = None, keep_frames: bool = False
) -> ScanResult:
    tracker = ProgressTracker(progress)
    name = codec_name or rig.config.scan.codec
    codecs = [make_codec(rig, p, name) for p in range(len(rig.config.projectors))]
    t0 = time.perf_counter()
    frames = capture(rig, codecs, tracker)
    capture_ms = (time.perf_counter() - t0) * 1e3
    result = reconstruct_frames(rig, name, frames, tracker, keep_frames)
    result.timings_ms = {"capture_ms": capture_ms, **result.timings_ms}
    return result


def reconstruct_frames(
    rig: Rig,
    codec_name: str,
    frames: dict[tuple[int, int], list[np.ndarray]],
    tracker: ProgressTracker,
    keep_frames: bool = False,
) -> ScanResult:
    """Decode and triangulate captured frames (fresh from the devices, or stored with a scan)."""
    codecs = [make_codec(rig, p, codec_name) for p in range(len(rig.config.projectors))]
    pairs: list[PairResult] = []
    elapsed = {"decode": 0.0, "triangulate": 0.0, "pointset": 0.0}
    n_pairs = len(frames)
    for i, ((p, c), images) in enumerate(sorted(frames.items())):
        t = time.perf_counter()
        try:
            corr = codecs[p].decode(images, (1 << rig.config.cameras[c].bit_depth) - 1)
        except DecodeError as exc:  # the frames the devices delivered do not fit: a failed scan
            raise ScanError(f"{rig.config.cameras[c].name}: {exc}") from exc
        elapsed["decode"] += time.perf_counter() - t
        tracker.report("decode", 0.6 + 0.3 * (i + 0.5) / n_pairs)
        pairs.append(reconstruct_pair(rig, p, c, corr, source=i, elapsed=elapsed))
        tracker.report("triangulate", 0.6 + 0.3 * (i + 1) / n_pairs)
    cloud = PointSet.concatenate([pair.points for pair in pairs])
    bytes_captured = sum(img.nbytes for images in frames.values() for img in images)
    return ScanResult(
        codec=codec_name,
        codec_params=codecs[0].params.model_dump(),
        pairs=pairs,
        cloud=cloud,
        frames_projected=sum(c.frame_count for c in codecs),
        bytes_captured=bytes_captured,
        timings_ms={f"{stage}_ms": seconds * 1e3 for stage, seconds in elapsed.items()},
        frames=frames if keep_frames else {},
    )
