"""Exposure from what the camera sees: a white and a black frame before the scan (the pre-capture),
their histogram, and the exposures a scan takes from it.

Auto-exposure sets each camera so that the brightest of its lit pixels (the `bright_quantile` of
the white frame over the pixels the projector lights) reads `target` of full scale: not a fixed
rule, the scene's own histogram. Where the white frame clips over more than the pixels that
quantile leaves out, what lies above full scale is unknown, and the exposure is cut by
`_CUT` and looked at again. Counts are taken as linear in exposure (a raw sensor; the simulator's
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
from rig.pipeline.capture import lit_stills
from rig.rig import Rig

_CUT = 0.25  # a white frame clipping too much: the next look at a quarter of the exposure
_LOOKS = 6  # pre-captures at most before auto-exposure settles on what it has
STEP = 4.0  # HDR exposures two stops apart
MIN_EXPOSURE_US, MAX_EXPOSURE_US = 1.0, 10_000_000.0  # the camera interface's bounds


@dataclass(frozen=True)
class ExposureSettings:
    target: float = 0.85  # of full scale, for the brightest lit pixels
    bright_quantile: float = 0.995
    dark_quantile: float = 0.02
    min_contrast: float = 0.15  # of full scale, white less black, at the darkest lit pixels
    lit_contrast: float = 0.008  # of full scale: a pixel the projector lights at all (2 counts of 8 bits)
    max_exposures: int = 10


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

    def as_dict(self) -> dict[str, object]:
        return {"mode": self.mode, "exposures_us": self.exposures_us, "looks": self.looks}


def require_exposure(camera: Camera, what: str) -> None:
    """DeviceStateError naming the control where `camera` cannot set its exposure."""
    if not camera.has_exposure:
        raise DeviceStateError(f"{camera.name}: {what} needs the camera's exposure control, which its driver lacks")


def auto_exposure(look: Look, settings: ExposureSettings) -> tuple[float, bool]:
    """The exposure that puts the brightest lit pixels at the target, from one look; and whether
    the look could tell (False: it clipped too much, the exposure returned is cut to look again)."""
    lit = look.lit(settings)
    if not lit.any():
        return _bounded(look.exposure_us / _CUT), False  # nothing lit: open up and look again
    if look.clipped_share(lit) > 1.0 - settings.bright_quantile:
        return _bounded(look.exposure_us * _CUT), False
    bright = float(np.quantile(look.white[lit], settings.bright_quantile))
    return _bounded(look.exposure_us * settings.target * look.full_scale / max(bright, 1.0)), True


def bracket(look: Look, settings: ExposureSettings) -> list[float]:
    """HDR exposures from one look (see the module docstring), shortest first."""
    lit = look.lit(settings)
    if not lit.any():
        return [look.exposure_us]
    white = look.white[lit].astype(np.float64)
    contrast = white - look.black[lit]
    brightest = float(white.max())
    if brightest >= look.full_scale:  # clipped already: the look says only that it is at least that
        shortest = look.exposure_us * _CUT
    else:
        shortest = look.exposure_us * settings.target * look.full_scale / max(brightest, 1.0)
    dark = max(float(np.quantile(contrast, settings.dark_quantile)), 1.0)
    longest = max(look.exposure_us * settings.min_contrast * look.full_scale / dark, shortest)
    count = min(settings.max_exposures, 1 + math.ceil(math.log(longest / shortest) / math.log(STEP) - 1e-9))
    return [_bounded(shortest * STEP**k) for k in range(max(count, 1))]


def _bounded(exposure_us: float) -> float:
    return float(min(max(exposure_us, MIN_EXPOSURE_US), MAX_EXPOSURE_US))


def precapture(rig: Rig, exposures_us: list[float]) -> list[Look]:
    """Per camera, a white and a black frame at its exposure in `exposures_us`: every projector
    white, then dark."""
    for camera, exposure in zip(rig.cameras, exposures_us, strict=True):
        camera.set_exposure_us(exposure)
    stills = lit_stills(rig, [list(range(len(rig.projectors))), []])
    return [
        Look(exposure, _one_channel(white), _one_channel(black), rig.config.cameras[c].full_scale)
        for (c, (white, black)), exposure in zip(stills.items(), exposures_us, strict=True)
    ]


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
