"""The simulated camera's sensor: radiance in, counts out.

Optical blur, then photo-electrons for the exposure (shot and read noise), clipped at the full
well (a pixel holds no more charge, whatever the gain), gain, the converter clipping at full
scale, the response curve and quantisation. What saturates here is what a real sensor clips: the
decoders must not read it as a point (rig.patterns.saturation).
"""

from __future__ import annotations

import cv2
import numpy as np

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
    surface at the reference distance; overwritten) over `exposure_us` at `gain`."""
    if params.blur_px > 0:
        radiance = cv2.GaussianBlur(radiance, (0, 0), params.blur_px, borderType=cv2.BORDER_REPLICATE)
    # each step in place where it can be: a render holds two float images, not seven
    electrons = np.multiply(
        radiance, np.float32(exposure_us / params.full_scale_exposure_us * params.full_well_e), out=radiance
    )
    sigma = np.add(electrons, np.float32(params.read_noise_e**2))
    np.sqrt(sigma, out=sigma)
    electrons += np.multiply(sigma, noise.frame(electrons.shape), out=sigma)
    del sigma
    np.minimum(electrons, np.float32(params.full_well_e), out=electrons)  # the well is full
    signal = np.multiply(electrons, np.float32(gain / params.full_well_e), out=electrons)
    np.clip(signal, 0.0, 1.0, out=signal)
    if params.gamma != 1.0:
        np.power(signal, np.float32(1.0 / params.gamma), out=signal)
    signal *= np.float32(sensor.full_scale)
    return np.rint(signal, out=signal).astype(np.uint8 if sensor.bit_depth <= 8 else np.uint16)
