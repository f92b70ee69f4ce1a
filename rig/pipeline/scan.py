"""One scan: show every pattern, capture every camera, decode, triangulate, merge."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from rig.errors import DecodeError, ScanError
from rig.geometry import CameraModel
from rig.kernels import kept_rows
from rig.opened_rig import Rig
from rig.patterns import Codec, CodecParams, Correspondence, FrameStream, RingSamples, codec_class, decode_streamed
from rig.pipeline.capture import CUE, capture
from rig.pipeline.colour import colour_beside_fill, colour_terms, sample_colours
from rig.pipeline.dense import PairTriangulator, pair_pointset, reject_isolated, texture_rgb
from rig.pipeline.merge import expected_error_mm, local_noise_mm, merge, triangulation_angles
from rig.pipeline.mesh import Mesh, grid_mesh
from rig.pipeline.organised import OrganisedCloud, PixelTerms, fast_terms, organised_cloud
from rig.pipeline.overlap import overlap_from_cue
from rig.pipeline.pointset import PointSet
from rig.pipeline.realign import align_pairs
from rig.pipeline.results import PairResult, ScanResult
from rig.pipeline.ring_triangulation import (
    RingPoints,
    across_ring_support,
    along_ring_support,
    ring_coverage,
    ring_pointset,
    triangulate_rings,
)
from rig.pipeline.surface import (
    RingBands,
    RingSurface,
    SurfaceSettings,
    covered_faces,
    fill_surface,
    surface_on_faces,
)
from rig.pipeline.triangulation import delaunay
from rig.progress import ProgressCallback, ProgressTracker
from rig.workers import POOL_WAIT_S, beside, pool


def make_codec(rig: Rig, projector: int, name: str | None = None, params: CodecParams | None = None) -> Codec:
    """The codec `name` (default: the config's) for one projector, with `params` or the config's."""
    name = name or rig.config.scan.codec
    cls = codec_class(name)
    params = params if params is not None else getattr(rig.config.scan, name, None)
    lut = rig.response_luts[projector] if rig.response_luts else None
    codec = cls(tuple(rig.config.projectors[projector].resolution), params, lut)
    codec.drops_outshone = rig.config.scan.exposure.drop_outshone
    codec.deblur_px = rig.config.scan.exposure.deblur_px
    if rig.intensity_masks:
        codec.intensity_mask = rig.intensity_masks[projector]
    return codec


def reconstruct_pair(
    rig: Rig, projector: int, camera: int, corr: Correspondence, source: int, elapsed: dict[str, float] | None = None
) -> PairResult:
    """Triangulate one pair's correspondence and build its PointSet; adds the seconds spent to
    `elapsed["triangulate"]` and `elapsed["pointset"]` when given."""
    t = time.perf_counter()
    model = rig.camera_models[camera]
    rings, counts, tri = None, dict(corr.counts), None
    if corr.samples is not None:
        rings, tri = _supported_rings(rig, projector, model, corr.samples, counts)
    elif (fast := pair_cloud(rig, projector, camera, corr)) is not None:
        cloud, cloud_counts = fast
        counts.update(cloud_counts)
    else:
        grid, valid = triangulator(rig, projector, camera).triangulate(corr)
        limit = rig.config.scan.max_depth_jump_mm
        if limit is not None:
            keep = reject_isolated(grid, valid, model, limit)
            counts["rejected_depth_jump"] = int((valid & ~keep).sum())
            grid[valid & ~keep] = np.nan
            valid = keep
    t_mid = time.perf_counter()
    # the kept samples' triangulation serves their normals and the surface between the rings
    if rings is not None and tri is None:
        tri = delaunay(kept_rows(rings.kept, rings.camera_xy)[0])
    if rings is not None:
        points, grid = ring_pointset(rings, model, corr, source, tri), None
    elif fast is not None:
        points, grid = cloud.into_pointset(source), None
    else:
        points = pair_pointset(grid, valid, model, corr, source=source)
    angles = triangulation_angles(points.points, model, rig.projector_models[projector])
    points = dataclasses.replace(points, angle=angles)
    counts["points"] = len(points)
    if elapsed is not None:
        elapsed["triangulate"] = elapsed.get("triangulate", 0.0) + t_mid - t
        elapsed["pointset"] = elapsed.get("pointset", 0.0) + time.perf_counter() - t_mid
    coverage = None if rings is None or corr.samples is None else ring_coverage(rings, corr.samples)
    surface = None
    if rings is not None and rig.config.scan.surface.interpolate:
        t = time.perf_counter()
        surface = ring_surface(rig, projector, camera, rings, corr, tri)
        counts.update({f"surface_{k}": v for k, v in surface.counts.items()})
        if elapsed is not None:
            elapsed["surface"] = elapsed.get("surface", 0.0) + time.perf_counter() - t
    return PairResult(projector, camera, corr, grid, points, rings, counts, coverage, surface)


def _supported_rings(
    rig: Rig, projector: int, model: CameraModel, samples: RingSamples, counts: dict[str, int]
) -> tuple[RingPoints, np.ndarray | None]:
    """The ring samples triangulated, those without support along and across their rings (within
    scan.max_depth_jump_mm) no longer kept, counted into `counts`; and the kept samples' Delaunay
    triangles, where begun beside the support across the rings (None: to be made)."""
    rings, ring_counts = triangulate_rings(model, rig.projector_models[projector], samples)
    counts.update(ring_counts)
    limit = rig.config.scan.max_depth_jump_mm
    if limit is None:
        return rings, None
    supported, tri = along_ring_support(rings, model, limit), None
    # the triangles of the samples kept so far, begun on the pool beside the support across the
    # rings (plain work: decision 0041), which seldom drops one more (none on any simulated bench):
    # where it does, they are made again
    speculative = pool().submit(delaunay, kept_rows(supported, rings.camera_xy)[0])
    across = across_ring_support(dataclasses.replace(rings, kept=supported), model, limit)
    if across[supported].all():
        tri = speculative.result(timeout=POOL_WAIT_S)
    else:
        speculative.cancel()  # if it has not begun; begun, it ends unread (and so would an error of its own)
    supported &= across
    counts["rejected_depth_jump"] = int((rings.kept & ~supported).sum())
    counts["ring_points"] = int(supported.sum())
    return dataclasses.replace(rings, kept=supported), tri


def ring_surface(
    rig: Rig, projector: int, camera: int, rings: RingPoints, corr: Correspondence, tri: np.ndarray | None = None
) -> RingSurface:
    """The surface between the kept ring samples (`tri`: their Delaunay triangles, where known), with
    holes where the projector left the camera dark."""
    config = rig.config.scan.surface
    points, xy, ring, directions = kept_rows(rings.kept, rings.points, rings.camera_xy, rings.ring, rings.directions)
    lit, bands, settings = ring_lit(rig, corr), ring_bands(corr), SurfaceSettings(max_gap_px=config.max_gap_px)
    devices = (rig.camera_models[camera], rig.projector_models[projector])
    faces = covered_faces(points, xy, ring, *devices, lit, settings, tri, directions)
    begun = None
    if config.colour != "white":  # the colour's terms from the faces, beside the faces' points
        colours = sample_colours(corr.texture, xy, corr.full_scale)
        samples = (points, faces.triangles.tri, ring)
        begun = beside().submit(colour_terms, samples, colours, config.colour, config.colour_neighbours)
    surface = surface_on_faces(points, xy, ring, faces, *devices, config.interpolant, settings, bands)
    del faces  # its pixel lists: the fill's peak of memory holds none
    if begun is None:
        return fill_surface(surface, xy, *devices, lit, bands, settings)
    # the triangles' pixels are coloured beside the fill, which leaves them alone
    stride = config.mesh_stride_px
    coloured = colour_beside_fill(surface, colours, config.colour, config.colour_neighbours, stride, begun)
    del begun  # the terms: the mix frees them, before the fill ends
    surface = fill_surface(surface, xy, *devices, lit, bands, settings)
    return dataclasses.replace(surface, colour=coloured(surface))


def ring_lit(rig: Rig, corr: Correspondence) -> np.ndarray:
    """(H, W) the pixels a ring pair's projector lit (scan.rings.black_threshold)."""
    return corr.quality >= rig.config.scan.rings.black_threshold


def ring_bands(corr: Correspondence) -> RingBands | None:
    """The ring codec's per-pixel annulus and angle, when it read them."""
    samples = corr.samples
    if samples is None or samples.ring_radii_px is None or "annulus" not in corr.extra:
        return None
    return RingBands(corr.extra["annulus"], corr.extra["angle"], samples.ring_radii_px, samples.center_px)


def pair_cloud(
    rig: Rig, projector: int, camera: int, corr: Correspondence
) -> tuple[OrganisedCloud, dict[str, int]] | None:
    """A dense correspondence's organised cloud by the fast path (rig.pipeline.organised): points,
    normals and colours as camera images; None where the pair needs the general path."""
    fast = organised_terms(rig, projector, camera, corr)
    if fast is None:
        return None
    origin = rig.camera_models[camera].center
    return organised_cloud(fast, origin, corr, rig.config.scan.max_depth_jump_mm)


def organised_terms(rig: Rig, projector: int, camera: int, corr: Correspondence) -> PixelTerms | None:
    """The pair's per-pixel terms for what `corr` codes, where the fast path (rig.pipeline.organised)
    can triangulate it: a dense correspondence of one axis or of both."""
    if corr.samples is not None or (corr.u is None and corr.v is None):
        return None
    coded = ("u" if corr.u is not None else "") + ("v" if corr.v is not None else "")
    return fast_terms(triangulator(rig, projector, camera), coded)


def triangulator(rig: Rig, projector: int, camera: int) -> PairTriangulator:
    """The pair's triangulator; its per-pixel terms are computed on first use and kept with the rig."""
    key = ("triangulator", projector, camera)
    if key not in rig.memo:
        rig.memo[key] = PairTriangulator(rig.camera_models[camera], rig.projector_models[projector])
    found = rig.memo[key]
    assert isinstance(found, PairTriangulator)
    return found


def run_scan(
    rig: Rig, codec_name: str | None = None, progress: ProgressCallback | None = None, keep_frames: bool = False
) -> ScanResult:
    tracker = ProgressTracker(progress)
    name = codec_name or rig.config.scan.codec
    codecs = [make_codec(rig, p, name) for p in range(len(rig.config.projectors))]
    streams = {
        (p, c): codecs[p].stream(rig.config.cameras[c].full_scale)
        for p in range(len(codecs))
        for c in range(len(rig.cameras))
        if is_reconstructed(rig, (p, c))
    }

    passed = [0]  # bytes of the frames handed on and not kept

    def decode_now(p: int, c: int, image: np.ndarray) -> None:  # decoding while capturing
        if not keep_frames:
            passed[0] += image.nbytes
        if (p, c) in streams:
            streams[(p, c)].add(image)

    t0 = time.perf_counter()
    # every reconstructed pair decodes as it captures: frames are kept only to be stored
    frames = capture(rig, codecs, tracker, decode_now, keep_frames=keep_frames)
    capture_ms = (time.perf_counter() - t0) * 1e3
    result = reconstruct_frames(rig, name, frames, tracker, keep_frames, streams, passed[0])
    result.timings_ms = {"capture_ms": capture_ms, **result.timings_ms}
    return result


def reconstruct_frames(
    rig: Rig,
    codec_name: str,
    frames: dict[tuple[int, int], list[np.ndarray]],
    tracker: ProgressTracker,
    keep_frames: bool = False,
    streams: dict[tuple[int, int], FrameStream] | None = None,
    passed_bytes: int = 0,
    decoded: dict[tuple[int, int], Correspondence] | None = None,
) -> ScanResult:
    """Decode and triangulate captured frames (fresh from the devices, or stored with a scan);
    `streams`: pairs whose frames were fed to their decoder as they were captured, to finish;
    `passed_bytes`: the bytes of captured frames that were decoded and not kept; `decoded`: pairs
    decoded already (an HDR scan's merged exposures)."""
    codecs = [make_codec(rig, p, codec_name) for p in range(len(rig.config.projectors))]
    pairs: list[PairResult] = []
    elapsed = {"decode": 0.0, "triangulate": 0.0, "pointset": 0.0}
    selected = sorted(k for k in frames if is_reconstructed(rig, k))
    for i, (p, c) in enumerate(selected):
        t = time.perf_counter()
        corr = (decoded or {}).get((p, c)) or _decoded(rig, codecs[p], c, frames[(p, c)], (streams or {}).get((p, c)))
        elapsed["decode"] += time.perf_counter() - t
        tracker.report("decode", 0.6 + 0.3 * (i + 0.5) / len(selected))
        pairs.append(reconstruct_pair(rig, p, c, corr, source=i, elapsed=elapsed))
        tracker.report("triangulate", 0.6 + 0.3 * (i + 1) / len(selected))
    cloud = PointSet.concatenate([pair.points for pair in pairs])
    merged_index, report, overlap = None, None, {}
    merge_config = rig.config.scan.merge
    if len(pairs) > 1 and merge_config.enabled:
        t = time.perf_counter()
        tracker.report("merge", 0.9)
        overlap = overlap_masks(rig, frames)
        report = {}
        if merge_config.refine == "icp":
            report["alignment"] = align_pairs(rig, pairs, merge_config.icp_max_distance_mm)
            cloud = PointSet.concatenate([pair.points for pair in pairs])
        quantized = codecs[0].quantized
        scores = np.concatenate([1.0 / pair_errors(rig, pair, quantized) for pair in pairs])
        cloud, merged_index, merged = merge(cloud, scores, merge_config.radius_mm, merge_config.voxel_mm)
        report.update(merged.as_dict())
        report["overlap_cue_pixels"] = {rig.config.cameras[c].name: int(m.sum()) for c, m in overlap.items()}
        elapsed["merge"] = time.perf_counter() - t
    bytes_captured = passed_bytes + sum(img.nbytes for images in frames.values() for img in images)
    mesh = scan_mesh(rig, pairs, elapsed)
    return ScanResult(
        codec=codec_name,
        codec_params=codecs[0].params.model_dump(),
        pairs=pairs,
        cloud=cloud,
        frames_projected=sum(c.frame_count for c in codecs) + len(frames.get((CUE, 0), [])),
        bytes_captured=bytes_captured,
        timings_ms={f"{stage}_ms": seconds * 1e3 for stage, seconds in elapsed.items()},
        frames=frames if keep_frames else {},
        descriptions=_descriptions(codecs) if keep_frames else {},
        merge=report,
        merged_index=merged_index,
        overlap=overlap,
        mesh=mesh,
    )


def _decoded(
    rig: Rig, codec: Codec, camera: int, frames: list[np.ndarray], stream: FrameStream | None
) -> Correspondence:
    """A pair's correspondence: its stream finished, or (frames stored with a scan) every frame
    streamed now."""
    try:
        if stream is None:
            return decode_streamed(codec, frames, rig.config.cameras[camera].full_scale)
        return stream.finish()
    except DecodeError as exc:  # the frames the devices delivered do not fit: a failed scan
        raise ScanError(f"{rig.config.cameras[camera].name}: {exc}") from exc


def is_reconstructed(rig: Rig, pair: tuple[int, int]) -> bool:
    """Whether a (projector, camera) pair's frames are reconstructed (the cue's are not; the config
    may choose the pairs)."""
    chosen = rig.config.scan.merge.pairs
    return pair[0] != CUE and (chosen is None or pair in {tuple(chosen_pair) for chosen_pair in chosen})


def _descriptions(codecs: list[Codec]) -> dict[int, dict[str, object]]:
    described = ((p, codec.description()) for p, codec in enumerate(codecs))
    return {p: spec.model_dump(mode="json") for p, spec in described if spec is not None}


def scan_mesh(rig: Rig, pairs: list[PairResult], elapsed: dict[str, float]) -> Mesh | None:
    """Every pair's interpolated surface in one mesh (None: no pair has one)."""
    surfaced = [pair for pair in pairs if pair.surface is not None]
    if not surfaced:
        return None
    t = time.perf_counter()
    stride = rig.config.scan.surface.mesh_stride_px
    mesh = Mesh.concatenate([pair_mesh(rig, pair, stride) for pair in surfaced])
    elapsed["mesh"] = time.perf_counter() - t
    return mesh


def pair_mesh(rig: Rig, pair: PairResult, stride: int) -> Mesh:
    """The pair's interpolated surface as a mesh, coloured between the rings or from the lit frame."""
    surface = pair.surface
    assert surface is not None
    if surface.colour is not None:
        colours = np.rint(np.clip(np.nan_to_num(surface.colour), 0.0, 1.0) * 255).astype(np.uint8)
    else:
        colours = texture_rgb(pair.correspondence)
    return grid_mesh(surface.grid, colours, rig.camera_models[pair.camera], stride)


def pair_errors(rig: Rig, pair: PairResult, quantized: bool = False) -> np.ndarray:
    """Each point's expected error along the surface normal (for choosing between pairs): from the
    triangulation geometry and decode quality, or, for quantised codes, the noise the pair's own
    points show about their local plane."""
    if quantized:
        return np.maximum(local_noise_mm(pair.points.points), 1e-6)
    corr = pair.correspondence
    coded = "u" if corr.v is None and corr.u is not None else "v" if corr.u is None and corr.v is not None else "both"
    camera, projector = rig.camera_models[pair.camera], rig.projector_models[pair.projector]
    return expected_error_mm(pair.points, camera, projector, coded)


def overlap_masks(rig: Rig, frames: dict[tuple[int, int], list[np.ndarray]]) -> dict[int, np.ndarray]:
    """Per camera, the pixels the intensity cue finds lit by several projectors."""
    ratio = rig.config.scan.merge.cue_ratio
    return {
        c: overlap_from_cue(images, rig.config.cameras[c].full_scale, ratio)
        for (p, c), images in frames.items()
        if p == CUE
    }
