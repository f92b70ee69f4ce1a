"""Exposure from what the camera sees: a white and a black frame before the scan (the pre-capture),
their histogram, and the exposures a scan takes from it.

Auto-exposure sets each camera to the exposure at which most of the pixels the projector lights
are well read, from the white frame's histogram over them: unclipped (within `target` of full
scale) and with `min_contrast` between white and black (auto_exposure): not a fixed rule, the
scene's own histogram, so a few highlights do not darken the rest. Where the white frame clips over
much of what is lit, what lies above full scale is unknown, and the exposure is cut by `_CUT` and
looked at again. Counts are taken as linear in exposure (a raw sensor; the simulator's
response curve is its `gamma`, 1 by default).

HDR brackets the exposure: from one at which the brightest lit pixel does not clip, in steps of
`STEP` (two stops), up to one at which the darkest lit pixels (`dark_quantile`) show the patterns
with `min_contrast` of full scale between white and black; at most `max_exposures`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from drivers.base import Camera
from drivers.errors import DeviceStateError
from rig.opened_rig import Rig
from rig.pipeline.capture import lit_stills

_CUT = 0.25  # a white frame clipping too much: the next look at a quarter of the exposure
_LOOKS = 6  # pre-captures at most before auto-exposure settles on what it has
_UNKNOWN = 0.25  # a look clipping more of its lit pixels than this cannot say what lies above
STEP = 4.0  # HDR exposures two stops apart
MIN_EXPOSURE_US, MAX_EXPOSURE_US = 1.0, 10_000_000.0  # the camera interface's bounds


@dataclass(frozen=True)
class ExposureSettings:
    target: float = 0.85  # of full scale, for the brightest lit pixels
    dark_quantile: float = 0.02
    min_contrast: float = 0.15  # of full scale, white less black, at the darkest lit pixels
    lit_contrast: float = 0.008  # of full scale: a pixel the projector lights at all (2 counts of 8 bits)
    max_exposures: int = 10
    max_clipped: float = 0.0005  # of the lit pixels, at the shortest HDR exposure


@dataclass(frozen=True)
class Look:
    """One camera's pre-capture: its white and black frames (one channel) at `exposure_us`."""

    exposure_us: float
    white: np.ndarray
    black: np.ndarray
    full_scale: int

    def lit(self, settings: ExposureSettings) -> np.ndarray:
        return (self.white.astype(np.int32) - self.black) >= settings.lit_contrast * self.full_scale

    def clipped_share(self, lit: np.ndarray) -> float:
        return float((self.white[lit] >= self.full_scale).mean()) if lit.any() else 0.0

    def summary(self, settings: ExposureSettings) -> dict[str, float]:
        """What the manifest records of a look: its exposure, the shares of pixels lit and clipped,
        and the white frame's quantiles over the lit pixels (a histogram in five numbers)."""
        lit = self.lit(settings)
        quantiles = np.quantile(self.white[lit], [0.02, 0.25, 0.5, 0.75, 0.995]) if lit.any() else np.zeros(5)
        return {
            "exposure_us": self.exposure_us,
            "lit_share": round(float(lit.mean()), 4),
            "clipped_share": round(self.clipped_share(lit), 4),
            **{f"white_q{q}": float(v) for q, v in zip((2, 25, 50, 75, 99.5), quantiles, strict=True)},
        }


@dataclass
class ExposureReport:
    """What the manifest records of a scan's exposures, per camera name."""

    mode: str
    exposures_us: dict[str, list[float]] = field(default_factory=dict)
    looks: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    projection: dict[str, object] | None = None  # adaptive projection (rig.pipeline.projection_mask)

    def as_dict(self) -> dict[str, object]:
        recorded = {"mode": self.mode, "exposures_us": self.exposures_us, "looks": self.looks}
        return recorded if self.projection is None else {**recorded, "adaptive_projection": self.projection}


def require_exposure(camera: Camera, what: str) -> None:
    """DeviceStateError naming the control where `camera` cannot set its exposure."""
    if not camera.has_exposure:
        raise DeviceStateError(f"{camera.name}: {what} needs the camera's exposure control, which its driver lacks")


def auto_exposure(look: Look, settings: ExposureSettings) -> tuple[float, bool]:
    """The exposure that reads the most lit pixels well, from one look: a scale k of the look's
    exposure puts pixel i at white_i * k, so it is well read where its white stays within the
    target of full scale and its contrast (white less black) reaches `min_contrast`; among the
    scales that read within 1 % of the most, the longest (the least noise). A highlight that no
    scale reads beside the rest is given up (HDR reads it). And whether the look could tell: one
    clipped over more than `_UNKNOWN` of its lit pixels cannot, and the exposure returned is cut
    to look again."""
    lit = look.lit(settings)
    if not lit.any():
        return _bounded(look.exposure_us / _CUT), False  # nothing lit: open up and look again
    if look.clipped_share(lit) > _UNKNOWN:
        return _bounded(look.exposure_us * _CUT), False
    white = look.white[lit].astype(np.float64)
    contrast = white - look.black[lit]
    read = white < look.full_scale  # a clipped pixel's true level is unknown: counted as lost
    ceiling = settings.target * look.full_scale / np.maximum(white[read], 1.0)  # the longest it stays under
    floor = settings.min_contrast * look.full_scale / np.maximum(contrast[read], 1e-3)  # the shortest it reads
    readable = floor <= ceiling
    floor, ceiling = np.sort(floor[readable]), np.sort(ceiling[readable])
    scales = np.geomspace(1.0 / 256.0, 256.0, 4097)  # 0.3 % apart
    # pixels read at a scale: those whose floor lies below it, less those whose ceiling does
    good = np.searchsorted(floor, scales, side="right") - np.searchsorted(ceiling, scales, side="left")
    if good.max() <= 0:
        return _bounded(look.exposure_us), True  # nothing reads well at any exposure: keep this one
    best = scales[np.flatnonzero(good >= 0.99 * good.max())[-1]]
    return _bounded(look.exposure_us * best), True


def bracket(look: Look, settings: ExposureSettings, short: Look | None = None) -> list[float]:
    """HDR exposures (see the module docstring), shortest first: the darkest lit pixels from
    `look`, the brightest from `short` (a look at a shorter exposure that clips little or nothing:
    shortest_looks), else from `look`."""
    lit = look.lit(settings)
    if not lit.any():
        return [look.exposure_us]
    contrast = look.white[lit].astype(np.float64) - look.black[lit]
    bright = short if short is not None else look
    brightest = float(bright.white[bright.lit(settings)].max(initial=0))
    if brightest >= bright.full_scale:  # clipped still: the look says only that it is at least that
        shortest = bright.exposure_us * _CUT
    else:
        shortest = bright.exposure_us * settings.target * bright.full_scale / max(brightest, 1.0)
    dark = max(float(np.quantile(contrast, settings.dark_quantile)), 1.0)
    longest = max(look.exposure_us * settings.min_contrast * look.full_scale / dark, shortest)
    count = min(settings.max_exposures, 1 + math.ceil(math.log(longest / shortest) / math.log(STEP) - 1e-9))
    return [_bounded(shortest * STEP**k) for k in range(max(count, 1))]


def _bounded(exposure_us: float) -> float:
    return float(min(max(exposure_us, MIN_EXPOSURE_US), MAX_EXPOSURE_US))


def within_range(camera: Camera, exposure_us: float) -> float:
    """`exposure_us` brought within what the camera's driver can set (Camera.exposure_range_us)."""
    low, high = camera.exposure_range_us
    return float(min(max(exposure_us, low), high))


def set_within_range(cameras: list[Camera], exposures_us: list[float]) -> list[float]:
    """Each camera set to its exposure, brought within its range; the exposures set."""
    chosen = [within_range(camera, e) for camera, e in zip(cameras, exposures_us, strict=True)]
    for camera, exposure in zip(cameras, chosen, strict=True):
        camera.set_exposure_us(exposure)
    return chosen


def precapture(rig: Rig, exposures_us: list[float]) -> list[Look]:
    """Per camera, a white and a black frame at its exposure in `exposures_us` (within the
    camera's range): every projector white, then dark."""
    exposures_us = set_within_range(rig.cameras, exposures_us)
    stills = lit_stills(rig, [list(range(len(rig.projectors))), []])
    return [
        Look(exposure, _one_channel(white), _one_channel(black), rig.config.cameras[c].full_scale)
        for (c, (white, black)), exposure in zip(stills.items(), exposures_us, strict=True)
    ]


def shortest_looks(rig: Rig, looks: list[Look], settings: ExposureSettings) -> list[Look]:
    """Per camera, a look at an exposure short enough that at most `max_clipped` of its lit pixels
    clip (a quarter of the last each time, at most _LOOKS looks): what a machined highlight needs."""
    for _ in range(_LOOKS):
        if all(look.clipped_share(look.lit(settings)) <= settings.max_clipped for look in looks):
            break
        shorter = [
            look.exposure_us * (_CUT if look.clipped_share(look.lit(settings)) > settings.max_clipped else 1.0)
            for look in looks
        ]
        looks = precapture(rig, [_bounded(e) for e in shorter])
    return looks


def settled_exposures(rig: Rig, settings: ExposureSettings) -> tuple[list[Look], dict[str, list[dict[str, float]]]]:
    """Auto-exposure for every camera (pre-captures until each has looked and could tell, at most
    _LOOKS): the last look of each, at its set exposure, and what each look saw, per camera name."""
    for camera in rig.cameras:
        require_exposure(camera, "auto-exposure")
    exposures = [camera.exposure_us for camera in rig.cameras]
    seen: dict[str, list[dict[str, float]]] = {camera.name: [] for camera in rig.cameras}
    looks = precapture(rig, exposures)
    for _ in range(_LOOKS):
        told = [auto_exposure(look, settings) for look in looks]
        for camera, look, (exposure, sure) in zip(rig.cameras, looks, told, strict=True):
            seen[camera.name].append({**look.summary(settings), "next_us": exposure, "settled": float(sure)})
        exposures = [exposure for exposure, _ in told]
        looks = precapture(rig, exposures)
        if all(sure for _, sure in told):
            break
    return looks, seen


def _one_channel(frame: np.ndarray) -> np.ndarray:
    return frame.max(axis=2) if frame.ndim == 3 else frame  # a channel clipping is a pixel clipping
