"""HDR by exposure bracketing: the scan's patterns captured at several exposures, each decoded as
it comes (saturated pixels already left out: rig.patterns.saturation), merged per pixel by the
exposure that reads it best (rig.pipeline.pass_merge). Adaptive projection's scans run here too:
one pass or two under different masks at one exposure (rig.pipeline.mask_passes), or a bracket
under one mask, each pass's decode with its masks' lean taken off (rig.pipeline.mask_skew).
"""

from __future__ import annotations

import time

import numpy as np

from rig.errors import ConfigError, ScanError
from rig.opened_rig import Rig
from rig.patterns import Codec, Correspondence, decode_streamed
from rig.pipeline.capture import CUE, Frames, capture
from rig.pipeline.exposure import (
    STEP,
    ExposureReport,
    ExposureSettings,
    Look,
    bracket,
    require_exposure,
    set_within_range,
    settled_exposures,
    shortest_looks,
    within_range,
)
from rig.pipeline.mask_skew import MaskSkew, Unleaned, unleaned
from rig.pipeline.pass_merge import merge_passes
from rig.pipeline.projection_mask import AdaptiveProjection, MaskSettings, masked_rig
from rig.pipeline.results import ScanResult
from rig.pipeline.scan import is_reconstructed, make_codec, reconstruct_frames, run_scan
from rig.progress import ProgressCallback, ProgressTracker


def run_hdr_scan(
    rig: Rig,
    exposures_us: list[list[float]],
    codec_name: str | None = None,
    progress: ProgressCallback | None = None,
    report: ExposureReport | None = None,
    adaptive: AdaptiveProjection | None = None,
    keep_frames: bool = False,
) -> ScanResult:
    """A scan whose patterns are captured at each camera's exposures (`exposures_us[camera]`, one
    list per camera, all of one length: the k-th pass sets each camera to its k-th), merged per
    pixel (rig.pipeline.pass_merge); the frames of the last pass are the ones kept for the overlap
    cue. With `keep_frames` every pass's frames are kept, one pass after another
    (reconstruct_exposures reads them again). `adaptive`: the masks each pass sends and what takes
    their lean off its decode (rig.pipeline.projection_mask); the blur each pass measured is
    recorded in `report`."""
    for camera in rig.cameras:
        require_exposure(camera, "HDR")
    passes = {len(e) for e in exposures_us}
    if len(passes) != 1 or len(exposures_us) != len(rig.cameras):
        raise ValueError(f"hdr: one list of exposures per camera, all of one length; got {exposures_us}")
    count = passes.pop()
    tracker = ProgressTracker(progress)
    name = codec_name or rig.config.scan.codec
    codecs = [make_codec(rig, p, name) for p in range(len(rig.config.projectors))]
    pairs = [(p, c) for p in range(len(codecs)) for c in range(len(rig.cameras)) if is_reconstructed(rig, (p, c))]
    decoded: dict[tuple[int, int], list[Unleaned]] = {pair: [] for pair in pairs}
    t0 = time.perf_counter()
    frames: dict[tuple[int, int], list[np.ndarray]] = {}
    kept: dict[tuple[int, int], list[np.ndarray]] = {}
    skews = {} if adaptive is None else adaptive.skews
    for k in range(count):
        set_within_range(rig.cameras, [exposures[k] for exposures in exposures_us])
        shown = rig if adaptive is None else adaptive.rig_of(k)
        for p, codec in enumerate(codecs):
            codec.intensity_mask = shown.intensity_masks[p] if shown.intensity_masks else None
        streams = {(p, c): codecs[p].stream(rig.config.cameras[c].full_scale) for p, c in pairs}

        def decode_now(p: int, c: int, image: np.ndarray, streams: dict = streams) -> None:
            if (p, c) in streams:
                streams[(p, c)].add(image)

        frames = capture(shown, codecs, tracker, decode_now, keep_frames=keep_frames)
        if keep_frames:
            for pair, images in frames.items():
                kept[pair] = images if pair[0] == CUE else [*kept.get(pair, []), *images]
        for pair, stream in streams.items():
            decoded[pair].append(unleaned(stream.finish(), skews.get(pair, []), k))
    capture_ms = (time.perf_counter() - t0) * 1e3
    merged = {pair: merge_passes(passes, len(skews.get(pair, [])) > 1) for pair, passes in decoded.items()}
    result = reconstruct_frames(rig, name, kept if keep_frames else frames, tracker, keep_frames, decoded=merged)
    result.timings_ms = {"capture_ms": capture_ms, **result.timings_ms}
    result.frames_projected = _projected(result, codecs, count)
    if count > 1:
        result.descriptions = {}  # a pattern description tells of one pass: others' readers would misread them
    if report is not None:
        blurs = {rig.config.pair_name(*pair): [one.blur_px for one in passes] for pair, passes in decoded.items()}
        result.exposure = _recorded(rig, report, exposures_us, blurs if adaptive is not None else {})
    return result


def _recorded(
    rig: Rig, report: ExposureReport, exposures_us: list[list[float]], blurs: dict[str, list[float | None]]
) -> dict[str, object]:
    """The manifest's `exposure`: `report` with each camera's exposures as set, and the lens blur
    adaptive projection measured on each pass of each pair (rig.pipeline.mask_skew)."""
    report.exposures_us = {
        camera.name: [within_range(camera, x) for x in e] for camera, e in zip(rig.cameras, exposures_us, strict=True)
    }
    if report.projection is not None and blurs:
        report.projection = {**report.projection, "projector_blur_px": blurs}
    return report.as_dict()


def scan_with_exposure(
    rig: Rig, codec_name: str | None = None, progress: ProgressCallback | None = None, keep_frames: bool = False
) -> ScanResult:
    """A scan at the exposures `scan.exposure` asks for: the cameras' own, one set for all, auto
    (from a pre-capture), or bracketed for HDR (auto, a count, or given); with adaptive projection,
    the patterns dimmed where the cameras would clip (rig.pipeline.projection_mask)."""
    config = rig.config.scan.exposure
    if config.exposure == "camera" and config.hdr is None and not config.adaptive_projection:
        return run_scan(rig, codec_name, progress, keep_frames)
    settings = ExposureSettings()
    _check_ranges(rig, config.exposure, config.hdr)
    if isinstance(config.exposure, float):
        for camera in rig.cameras:
            require_exposure(camera, "scan.exposure")
            camera.set_exposure_us(config.exposure)
    mode = "hdr" if config.hdr is not None else str(config.exposure)
    if not config.adaptive_projection:
        return _scan_at_exposures(rig, settings, ExposureReport(mode), codec_name, progress, keep_frames)
    for camera in rig.cameras:
        require_exposure(camera, "adaptive projection")
    tracker = ProgressTracker(progress)
    fixed = config.exposure if isinstance(config.exposure, float) else None
    passes = config.adaptive_passes if config.hdr is None else 1  # a bracket takes one mask at every exposure
    adaptive = masked_rig(rig, settings, fixed, tracker.part(0.0, 0.3), MaskSettings(passes=passes), codec_name)
    report = ExposureReport("adaptive projection + hdr" if config.hdr is not None else "adaptive projection")
    report.projection = adaptive.record
    if config.hdr is None:  # the masked rig's cameras are at the scan's exposure, each pass at it
        exposures = [[camera.exposure_us] * adaptive.passes for camera in rig.cameras]
        rest = tracker.part(0.3, 1.0)
        result = run_hdr_scan(adaptive.rig, exposures, codec_name, rest, report, adaptive, keep_frames)
    else:
        result = _scan_at_exposures(
            adaptive.rig, settings, report, codec_name, tracker.part(0.3, 1.0), keep_frames, adaptive
        )
    result.frames_projected += adaptive.prescan_frames
    result.mask_skews = adaptive.skews
    return result


def _check_ranges(rig: Rig, exposure: object, hdr: object) -> None:
    """ConfigError naming the field where an exposure given in microseconds is outside a camera's range."""
    given = [("scan.exposure.exposure", exposure)] if isinstance(exposure, float) else []
    given += [("scan.exposure.hdr", e) for e in hdr] if isinstance(hdr, list) else []
    problems = [
        f"{field}: {value:g} us is outside {camera.name}'s exposures ({low:g} to {high:g} us)"
        for field, value in given
        for camera in rig.cameras
        for low, high in [camera.exposure_range_us]
        if not low <= value <= high
    ]
    if problems:
        raise ConfigError("scan", problems)


def _scan_at_exposures(
    rig: Rig,
    settings: ExposureSettings,
    report: ExposureReport,
    codec_name: str | None,
    progress: ProgressCallback | None,
    keep_frames: bool,
    adaptive: AdaptiveProjection | None = None,
) -> ScanResult:
    """A scan at one exposure (the cameras' as set, or auto) or bracketed for HDR (rig.config);
    `adaptive`: one mask for every exposure of the bracket."""
    config = rig.config.scan.exposure
    looks = None
    if config.exposure == "auto" or config.hdr == "auto" or isinstance(config.hdr, int):
        looks, report.looks = settled_exposures(rig, settings)
    if config.hdr is None:
        result = run_scan(rig, codec_name, progress, keep_frames)
        report.exposures_us = {camera.name: [camera.exposure_us] for camera in rig.cameras}
        result.exposure = report.as_dict()
        return result
    exposures = bracketed(rig, config.hdr, looks, settings)
    return run_hdr_scan(rig, exposures, codec_name, progress, report, adaptive, keep_frames)


def bracketed(
    rig: Rig, hdr: int | str | list[float], looks: list[Look] | None, settings: ExposureSettings
) -> list[list[float]]:
    """Each camera's HDR exposures, all of one length (every camera takes every pass): those given,
    or bracketed from auto-exposure's `looks` (a count: that many from the shortest); the cameras
    are left where auto-exposure settled."""
    if isinstance(hdr, list):
        return [list(hdr) for _ in rig.cameras]
    if looks is None:
        raise ValueError("hdr: a bracket needs auto-exposure's looks")
    short = shortest_looks(rig, looks, settings)
    exposures = [bracket(look, settings, brief) for look, brief in zip(looks, short, strict=True)]
    for camera, look in zip(rig.cameras, looks, strict=True):  # back to where auto-exposure settled
        camera.set_exposure_us(look.exposure_us)
    if isinstance(hdr, int):
        exposures = [[e[0] * STEP**k for k in range(hdr)] for e in exposures]
    longest = max(len(e) for e in exposures)
    return [e + [e[-1]] * (longest - len(e)) for e in exposures]


def _projected(result: ScanResult, codecs: list[Codec], passes: int) -> int:
    """Patterns projected: every codec's, once per pass, and the overlap cue's stills once."""
    return passes * sum(c.frame_count for c in codecs) + (result.frames_projected - sum(c.frame_count for c in codecs))


def reconstruct_exposures(
    rig: Rig,
    codec_name: str,
    frames: Frames,
    passes: int,
    tracker: ProgressTracker,
    skews: dict[tuple[int, int], list[MaskSkew]] | None = None,
) -> ScanResult:
    """A stored HDR scan's frames (each pair's passes one after another, as run_hdr_scan keeps
    them) decoded pass by pass, merged per pixel as the scan merged them, and triangulated; with an
    adaptive projection's kept masks (`skews`), each pass's decode has their lean taken off first."""
    codecs = [make_codec(rig, p, codec_name) for p in range(len(rig.config.projectors))]
    merged: dict[tuple[int, int], Correspondence] = {}
    last: Frames = {pair: images for pair, images in frames.items() if pair[0] == CUE}
    for (p, c), images in frames.items():
        if p == CUE:
            continue
        per_pass = codecs[p].frame_count
        if len(images) != passes * per_pass:
            raise ScanError(
                f"{rig.config.cameras[c].name}: {len(images)} frames kept, not {passes} passes of {per_pass}"
            )
        chunks = [images[k * per_pass : (k + 1) * per_pass] for k in range(passes)]
        last[(p, c)] = chunks[-1]
        if is_reconstructed(rig, (p, c)):
            full_scale = rig.config.cameras[c].full_scale
            corrs = [decode_streamed(codecs[p], chunk, full_scale) for chunk in chunks]
            pair_skews = (skews or {}).get((p, c), [])
            passes_read = [unleaned(one, pair_skews, k) for k, one in enumerate(corrs)]
            merged[(p, c)] = merge_passes(passes_read, len(pair_skews) > 1)
    result = reconstruct_frames(rig, codec_name, last, tracker, decoded=merged)
    result.frames_projected = _projected(result, codecs, passes)
    return result
