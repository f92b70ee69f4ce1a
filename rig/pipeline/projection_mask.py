"""Adaptive projection: each projector dims its patterns where the camera would clip, so that one
exposure long enough for the darkest lit surface reads a machined highlight too (after Li & Kofman,
and Waddington & Kofman: a per-pixel projector intensity from a pre-scan).

1. Auto-exposure, and a look short enough that highlights stop clipping (rig.pipeline.exposure).
2. A look with every pattern at half its levels says how light follows the level sent (the
   projector's response exponent: 2.2 on a video projector, 1 through a calibrated response LUT).
3. The scan's exposure: the one at which the darkest lit pixels read (as HDR's longest), but no
   longer than the masks can make up for: a mask scales a pattern's levels, at most
   `dynamic_range` times (dimmed 16 times, a pattern keeps 16 of its 256 levels).
4. A pre-scan at the short exposure, whose points say which projector pixel lights which camera
   pixel (each pixel's point projected into the projector; a pixel without a point takes its
   nearest neighbour's within `MAP_REACH_PX`).
5. Each camera pixel's white at the scan's exposure is foretold from the short look (counts are
   linear in exposure), and the share of the projector's light it can take without passing the
   target; each projector pixel takes the least share of the camera pixels it lights, spread over
   `margin_px` (the map's error, the lenses' blur) and smoothed, so the mask's own edges stay soft;
   the share of light becomes a scale of the levels through the response exponent.
6. A look with the masks at the scan's exposure: where a pixel still passes the target (a pixel
   the pre-scan could not map; a response not quite a power), its projector pixels are dimmed
   again, `rounds` times at most.
7. The scan with the masks; where a mask steps, its lens's blur leans the patterns toward the
   brighter side, and each decode has that lean taken off (rig.pipeline.mask_skew). Where more than
   `second_pass_share` of the lit projector pixels lie in the band about the masks' steps that one
   pass would lose (many edges of strong contrast), two passes at the same exposure with the steps
   on either side of each edge (rig.pipeline.mask_passes).

The masks leave every codec as it is: each pattern, its white and dark frames alike, is sent dimmed
(rig.patterns.base.sent_levels), and a codec compares each pixel with its own white and dark.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from rig.geometry import CameraModel
from rig.opened_rig import Rig
from rig.pipeline.exposure import (
    ExposureSettings,
    Look,
    precapture,
    settled_exposures,
    shortest_looks,
    within_range,
)
from rig.pipeline.mask_passes import step_band, two_pass_masks
from rig.pipeline.mask_skew import MaskSkew
from rig.pipeline.results import PairResult
from rig.pipeline.scan import make_codec, run_scan
from rig.progress import ProgressCallback, ProgressTracker

MAP_REACH_PX = 8  # a camera pixel without a pre-scan point takes its nearest mapped neighbour's within this


@dataclass(frozen=True)
class MaskSettings:
    dynamic_range: float = 16.0  # the most a mask dims (a dimmed pattern keeps 256 / 16 levels)
    margin_px: int = 1  # projector pixels about each dimmed one dimmed as much (the map's error)
    smooth_px: float = 0.0  # the mask's edges softened by this much (Gaussian sigma, projector pixels)
    rounds: int = 2  # looks with the masks, each dimming again where a pixel still clips
    max_shift_px: float = 0.25  # a pixel the mask's steps lean further than this is left out (mask_skew)
    fallback_blur_px: float = 0.75  # the projector's blur where the scan cannot measure it (mask_skew)
    passes: int | str = "auto"  # at the one exposure: 1, 2, or auto (second_pass_share decides; mask_passes)
    second_pass_share: float = 0.01  # two passes where more lit projector pixels lie in a step band (mask_passes)


def scan_exposure(look: Look, short: Look, settings: ExposureSettings, light_range: float) -> float:
    """The exposure an adaptive scan takes (step 3 of the module docstring): `light_range`, the
    most the masks may dim the light."""
    lit = look.lit(settings)
    if not lit.any():
        return look.exposure_us
    contrast = look.white[lit].astype(np.float64) - look.black[lit]
    dark = max(float(np.quantile(contrast, settings.dark_quantile)), 1.0)
    darkest_reads = look.exposure_us * settings.min_contrast * look.full_scale / dark
    brightest = max(float(short.white[short.lit(settings)].max(initial=0)), 1.0)
    brightest_reaches = short.exposure_us * settings.target * short.full_scale / brightest
    return float(min(darkest_reads, brightest_reaches * light_range))


def light_share(short: Look, exposure_us: float, settings: ExposureSettings) -> np.ndarray:
    """(H, W) the share of the projector's light each camera pixel can take at `exposure_us`
    without its white passing the target (1 where it never does): its white and dark at the short
    look scaled to the exposure (a pixel clipped at the short look counts as at full scale)."""
    scale = exposure_us / short.exposure_us
    white, black = short.white.astype(np.float64) * scale, short.black.astype(np.float64) * scale
    room = settings.target * short.full_scale - black
    with np.errstate(divide="ignore", invalid="ignore"):
        share = room / (white - black)
    return np.clip(np.nan_to_num(share, nan=1.0, posinf=1.0), 0.0, 1.0)


def projector_pixels(pair: PairResult, projector: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) projector columns and rows each camera pixel's pre-scan point lies at, NaN where no
    point lies within MAP_REACH_PX (see the module docstring)."""
    grid = pair.grid
    shape = grid.shape[:2]
    known = np.isfinite(grid).all(axis=2)
    u, v = np.full(shape, np.nan), np.full(shape, np.nan)
    if not known.any():
        return u, v
    u[known], v[known], _ = projector.project_columns(grid[known])
    distance, (rows, cols) = ndimage.distance_transform_edt(~known, return_indices=True)
    near = distance <= MAP_REACH_PX
    return np.where(near, u[rows, cols], np.nan), np.where(near, v[rows, cols], np.nan)


def scattered_mask(
    size: tuple[int, int], u: np.ndarray, v: np.ndarray, share: np.ndarray, settings: MaskSettings
) -> np.ndarray:
    """(height, width) of a projector of `size` (width, height): each pixel the least `share` of the
    camera pixels it lights (columns `u`, rows `v`), spread and softened (see the module docstring)."""
    width, height = size
    mask = np.ones((height, width), np.float32)
    dim = np.isfinite(u) & np.isfinite(v) & (share < 1.0)
    cols, rows = np.rint(u[dim]).astype(np.int64), np.rint(v[dim]).astype(np.int64)
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    np.minimum.at(mask, (rows[inside], cols[inside]), share[dim][inside].astype(np.float32))
    spread = 2 * settings.margin_px + 1
    mask = cv2.erode(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (spread, spread)))
    if settings.smooth_px > 0:
        mask = cv2.GaussianBlur(mask, (0, 0), settings.smooth_px, borderType=cv2.BORDER_REPLICATE)
    return np.clip(mask, 1e-6, 1.0)  # a share, in light: the floor is in levels (_dimmed)


@dataclass(frozen=True)
class AdaptiveProjection:
    """What masked_rig made: the rig with its (first pass's) masks, sharing the devices; what it
    did, for the manifest; the pattern frames its pre-scan projected; `pass_masks`: each pass's
    masks, one per projector (one entry: the same masks for every pass, as an HDR bracket takes
    them); and per (projector, camera) pair, per entry of `pass_masks`, what takes the masks' lean
    off its decode (rig.pipeline.mask_skew)."""

    rig: Rig
    record: dict[str, object]
    prescan_frames: int
    pass_masks: list[list[np.ndarray]]
    skews: dict[tuple[int, int], list[MaskSkew]]

    @property
    def passes(self) -> int:
        return len(self.pass_masks)

    def rig_of(self, k: int) -> Rig:
        """The rig sending pass `k`'s masks."""
        return dataclasses.replace(self.rig, intensity_masks=self.pass_masks[min(k, self.passes - 1)])


@dataclass
class _Map:
    """Where one (projector, camera) pair's camera pixels fall in the projector."""

    projector: int
    camera: int
    u: np.ndarray
    v: np.ndarray
    own: np.ndarray  # the camera pixels the pre-scan gave a point of their own


def masked_rig(
    rig: Rig,
    settings: ExposureSettings,
    exposure_us: float | None = None,
    progress: ProgressCallback | None = None,
    mask_settings: MaskSettings | None = None,
    codec_name: str | None = None,
) -> AdaptiveProjection:
    """The rig with an intensity mask for each projector (see the module docstring), each camera set
    to the scan's exposure (`exposure_us` for every camera, else step 3), for a scan with the codec
    `codec_name` (default: the config's). The pre-scan takes that codec where it is dense, else
    the pilot's (scan.adaptive.pilot_codec): sparse rings would map only the pixels beside them."""
    mask_settings = mask_settings or MaskSettings()
    tracker = ProgressTracker(progress)
    looks, seen = settled_exposures(rig, settings)
    shorts = shortest_looks(rig, looks, settings)
    exponent = response_exponent(rig, shorts, settings)  # leaves the cameras at the short looks' exposures
    light_range = mask_settings.dynamic_range**exponent
    exposures = [
        within_range(
            camera, exposure_us if exposure_us is not None else scan_exposure(look, short, settings, light_range)
        )
        for camera, look, short in zip(rig.cameras, looks, shorts, strict=True)
    ]
    axes = make_codec(rig, 0, codec_name).coded_axes()
    pre_codec = codec_name if axes else rig.config.scan.adaptive.pilot_codec
    pre = run_scan(rig, pre_codec, progress=tracker.part(0.0, 0.9, "pre-scan "))  # at the short looks' exposures
    maps = [_map_of(pair, rig.projector_models[pair.projector]) for pair in pre.pairs]
    masks = [np.ones((p.resolution[1], p.resolution[0]), np.float32) for p in rig.projectors]
    shares = [light_share(short, exposure, settings) for short, exposure in zip(shorts, exposures, strict=True)]
    masks, rounds = _looked_again(
        rig,
        _dimmed(rig, masks, maps, shares, mask_settings, exponent),
        maps,
        exposures,
        settings,
        mask_settings,
        exponent,
    )
    for camera, exposure in zip(rig.cameras, exposures, strict=True):
        camera.set_exposure_us(exposure)
    tracker.report("pre-scan", 1.0)
    pass_masks, bands = _pass_masks(masks, maps, exponent, mask_settings, axes)
    record: dict[str, object] = {
        "exposures_us": {camera.name: e for camera, e in zip(rig.cameras, exposures, strict=True)},
        "looks": seen,
        "prescan_exposures_us": {camera.name: s.exposure_us for camera, s in zip(rig.cameras, shorts, strict=True)},
        "response_exponent": round(exponent, 3),
        "rounds": rounds,
        "masks": [_summary(mask) for mask in masks],
        "passes": len(pass_masks),
        "step_band": {rig.config.pair_name(p, c): round(band, 4) for (p, c), band in bands.items()},
    }
    skews = _skews(pass_masks, maps, exponent, mask_settings)
    return AdaptiveProjection(
        dataclasses.replace(rig, intensity_masks=pass_masks[0]), record, pre.frames_projected, pass_masks, skews
    )


def _skews(
    pass_masks: list[list[np.ndarray]], maps: list[_Map], exponent: float, settings: MaskSettings
) -> dict[tuple[int, int], list[MaskSkew]]:
    """Per pair, per pass's masks, what takes their lean off its decode (rig.pipeline.mask_skew)."""
    return {
        (m.projector, m.camera): [
            MaskSkew(
                sent[m.projector] ** np.float32(exponent),
                m.u,
                m.v,
                m.own,
                settings.max_shift_px,
                settings.fallback_blur_px,
            )
            for sent in pass_masks
        ]
        for m in maps
    }


def _looked_again(
    rig: Rig,
    masks: list[np.ndarray],
    maps: list[_Map],
    exposures: list[float],
    settings: ExposureSettings,
    mask_settings: MaskSettings,
    exponent: float,
) -> tuple[list[np.ndarray], int]:
    """`masks` dimmed again where a look with them at the scan's `exposures` still passes the target
    (step 6), at most `mask_settings.rounds` times; and the rounds that dimmed."""
    rounds = 0
    for rounds in range(1, mask_settings.rounds + 1):
        looks = precapture(dataclasses.replace(rig, intensity_masks=masks), exposures)
        over = [_over_target(look, settings) for look in looks]
        if all((share >= 1.0).all() for share in over):
            return masks, rounds - 1
        masks = _dimmed(rig, masks, maps, over, mask_settings, exponent)
    return masks, rounds


def _pass_masks(
    masks: list[np.ndarray],
    maps: list[_Map],
    exponent: float,
    settings: MaskSettings,
    axes: str,
) -> tuple[list[list[np.ndarray]], dict[tuple[int, int], float]]:
    """Each pass's masks: `masks` for one pass, or two passes' (rig.pipeline.mask_passes) where
    `settings.passes` is 2, or "auto" and more than `second_pass_share` of the projector pixels
    lighting a pair's mapped camera pixels lie in one pass's step band along the coded `axes`
    (step_band); and that share, per pair. A sparse codec (no coded axes: ring samples, which keep
    their lean) takes one pass unless asked for two: on a checker, a second pass read more ring
    samples but worse (rms 0.24 to 0.40 mm on the small bench)."""
    bands = {
        (m.projector, m.camera): step_band(
            masks[m.projector] ** np.float32(exponent),
            m.u,
            m.v,
            settings.max_shift_px,
            settings.fallback_blur_px,
            axes or "uv",
        )
        for m in maps
    }
    wide = max(bands.values(), default=0.0) > settings.second_pass_share
    two = settings.passes == 2 or (settings.passes == "auto" and wide and bool(axes))
    return (two_pass_masks(masks, settings.margin_px) if two else [masks]), bands


def _map_of(pair: PairResult, projector: CameraModel) -> _Map:
    u, v = projector_pixels(pair, projector)
    return _Map(pair.projector, pair.camera, u, v, np.isfinite(pair.grid).all(axis=2))


def response_exponent(rig: Rig, shorts: list[Look], settings: ExposureSettings) -> float:
    """How light follows the level sent: light ~ level ** exponent, from a look with every
    projector at half its levels beside the short looks at full (the median over pixels well lit
    and unclipped in both; 1 where none is)."""
    half = [np.full((p.resolution[1], p.resolution[0]), 0.5, np.float32) for p in rig.projectors]
    dimmed = precapture(dataclasses.replace(rig, intensity_masks=half), [s.exposure_us for s in shorts])
    ratios = []
    for full, low in zip(shorts, dimmed, strict=True):
        black = full.black.astype(np.float64)
        contrast = full.white - black
        good = (contrast >= settings.min_contrast * full.full_scale) & (full.white < full.full_scale)
        if good.any():
            ratios.append(np.median((low.white[good] - black[good]) / contrast[good]))
    if not ratios:
        return 1.0
    ratio = float(np.clip(np.median(ratios), 1e-3, 0.999))
    return float(np.clip(np.log(ratio) / np.log(128.0 / 255.0), 0.5, 4.0))


def _dimmed(
    rig: Rig,
    masks: list[np.ndarray],
    maps: list[_Map],
    shares: list[np.ndarray],
    settings: MaskSettings,
    exponent: float,
) -> list[np.ndarray]:
    """`masks` (scales of the levels sent) each times the scale that gives the share of light the
    cameras' `shares` ask of it (scattered_mask), light ~ level ** `exponent`."""
    dimmed = [mask.copy() for mask in masks]
    for m in maps:
        size = rig.projectors[m.projector].resolution
        light = scattered_mask(size, m.u, m.v, shares[m.camera], settings)
        dimmed[m.projector] *= light ** np.float32(1.0 / exponent)
    return [np.clip(mask, 1.0 / settings.dynamic_range, 1.0) for mask in dimmed]


def _over_target(look: Look, settings: ExposureSettings) -> np.ndarray:
    """(H, W) how much more each pixel of a masked look must be dimmed: the target over its white
    where it passes the target by more than a tenth, a quarter where it clips, else 1."""
    white = look.white.astype(np.float64)
    ceiling = settings.target * look.full_scale
    share = np.where(white > 1.1 * ceiling, ceiling / np.maximum(white, 1.0), 1.0)
    return np.where(white >= look.full_scale, 0.25, share)


def _summary(mask: np.ndarray) -> dict[str, float]:
    return {
        "dimmed_share": round(float((mask < 0.999).mean()), 4),
        "least": round(float(mask.min()), 4),
        "mean": round(float(mask.mean()), 4),
    }
