"""The simulated camera's sensor: radiance in, counts out.

Optical blur, then photo-electrons for the exposure (shot and read noise), clipped at the full
well (a pixel holds no more charge, whatever the gain), gain, the converter clipping at full
scale, the response curve and quantisation. What saturates here is what a real sensor clips: the
decoders must not read it as a point (rig.patterns.saturation).
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

from drivers.options import CameraSettings, SimCameraOptions


class NoiseTable:
    """Frames of standard normal noise: a window at a random offset into a table four frames long,
    drawn once (drawing 1.3 M normals per frame took 17 ms, most of a render). Within a frame the
    values are independent, and so are one pixel's from frame to frame; between two frames, pixels
    a random offset apart (typically hundreds of rows) share values, which no decoder's few-pixel
    neighbourhood sees."""

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._noise: np.ndarray | None = None

    def frame(self, shape: tuple[int, ...]) -> np.ndarray:
        size = int(np.prod(shape))
        if self._noise is None or len(self._noise) < 4 * size:
            self._noise = self._rng.standard_normal(max(4 * size, 1 << 20), dtype=np.float32)
        start = int(self._rng.integers(0, len(self._noise) - size + 1))
        return self._noise[start : start + size].reshape(shape)


def expose(
    radiance: np.ndarray,
    exposure_us: float,
    gain: float,
    sensor: CameraSettings,
    params: SimCameraOptions,
    noise: NoiseTable,
) -> np.ndarray:
    """The counts (uint8 or uint16) a sensor reads from `radiance` (float32, relative to a white
    surface at the reference distance; it may be overwritten) over `exposure_us` at `gain`."""
    if params.blur_px > 0:
        # in place (the same values as into a new image): no image-sized array per frame
        radiance = cv2.GaussianBlur(radiance, (0, 0), params.blur_px, dst=radiance, borderType=cv2.BORDER_REPLICATE)
    radiance = np.ascontiguousarray(radiance)
    terms = (
        np.float32(exposure_us / params.full_scale_exposure_us * params.full_well_e),  # electrons per unit
        np.float32(params.read_noise_e**2),
        np.float32(params.full_well_e),
        np.float32(gain / params.full_well_e),  # signal per electron
    )
    flat, shot = radiance.reshape(-1), noise.frame(radiance.shape).reshape(-1)
    counts = np.empty(radiance.shape, np.uint8 if sensor.bit_depth <= 8 else np.uint16)
    if params.gamma == 1.0:  # one pass, the float image never written back
        _counts(flat, shot, terms, np.float32(sensor.full_scale), counts.reshape(-1))
        return counts
    _signal_in_place(flat, shot, terms)
    np.power(radiance, np.float32(1.0 / params.gamma), out=radiance)
    radiance *= np.float32(sensor.full_scale)
    return np.rint(radiance, out=counts, casting="unsafe")


@njit(nogil=True, cache=True, inline="always")
def _signal(radiance: np.float32, shot: np.float32, terms: tuple[np.float32, ...]) -> np.float32:
    """A pixel's signal in [0, 1]: electrons with shot and read noise (`shot` standard normal),
    clipped at the full well, times the gain; float32 throughout, in numpy's order of operations."""
    per_unit, read_variance, full_well, per_electron = terms
    electrons = radiance * per_unit
    electrons = electrons + np.sqrt(electrons + read_variance) * shot
    signal = min(electrons, full_well) * per_electron  # the well is full
    return min(max(signal, np.float32(0)), np.float32(1))


@njit(nogil=True, cache=True)
def _counts(
    radiance: np.ndarray, shot: np.ndarray, terms: tuple[np.float32, ...], full_scale: np.float32, out: np.ndarray
) -> None:
    """The counts of a linear sensor (gamma 1) from flat radiance: one pass, every step in registers
    (seven numpy passes over a 1280x1024 image took 7 ms, a third of a render)."""
    for i in range(radiance.size):
        out[i] = np.rint(_signal(radiance[i], shot[i], terms) * full_scale)


@njit(nogil=True, cache=True)
def _signal_in_place(radiance: np.ndarray, shot: np.ndarray, terms: tuple[np.float32, ...]) -> None:
    """Each pixel's signal (_signal) written over its flat radiance: a non-linear sensor's, before
    its gamma."""
    for i in range(radiance.size):
        radiance[i] = _signal(radiance[i], shot[i], terms)
