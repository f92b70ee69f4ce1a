"""Accuracy of a scan's colour against the bench's true albedo.

A camera sees albedo times the light falling on the surface, times an exposure it does not know.
So each estimate is first divided by the true white-frame irradiance at its pixel (the shading:
incidence, fall-off, ambient), then scaled by the one gain that fits it best to the truth (least
squares over all pixels and channels): what remains is the error of the colour itself, the same
way for an interpolated colour and for the white frame's (the upper bound).
"""

from __future__ import annotations

import numpy as np

from rig.opened_rig import PixelTruth
from rig.pipeline import PairResult, texture_rgb

# Pixels the projector lights this weakly (relative to the median) carry mostly noise once unshaded.
_MIN_RELATIVE_IRRADIANCE = 0.2
_BATCH = 1 << 16
_SRGB_TO_XYZ = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
_D65 = np.array([0.95047, 1.0, 1.08883])


def colour_metrics(pair: PairResult, truth: PixelTruth, stride: int = 2) -> dict[str, float | int | None]:
    """PSNR (dB), RGB rms and mean CIEDE2000 of the pair's interpolated colour (when it has one)
    and of its lit frame, both on the pixels the interpolated colour covers (or, without one, the
    interpolated surface) where the true surface is lit, on every `stride`-th row and column (the
    mesh's vertices: every simulated ring scan measures this, so it is kept cheap)."""
    surface = pair.surface
    if surface is None:
        return {}
    covered = surface.valid if surface.colour is None else np.isfinite(surface.colour).all(axis=2)
    on_grid = np.zeros_like(covered)
    on_grid[::stride, ::stride] = True
    mask = covered & on_grid & truth.hit & truth.lit
    irradiance = truth.white_irradiance
    if mask.any():
        mask &= irradiance >= _MIN_RELATIVE_IRRADIANCE * np.median(irradiance[truth.hit & truth.lit])
    white = texture_rgb(pair.correspondence)  # 8-bit: its pixels are scaled as they are read
    estimates = [("white_colour", white, 255.0)]
    estimates += [("colour", surface.colour, None)] if surface.colour is not None else []
    metrics: dict[str, float | int | None] = {"colour_pixels": int(mask.sum())}
    for name, estimate, full_scale in estimates:
        metrics.update({f"{name}_{k}": v for k, v in albedo_errors(estimate, truth, mask, full_scale).items()})
    return metrics


def albedo_errors(
    estimate: np.ndarray, truth: PixelTruth, mask: np.ndarray, full_scale: float | None = None
) -> dict[str, float | None]:
    """PSNR, RGB rms and mean dE2000 of an RGB estimate (H, W, 3, any exposure; levels over
    `full_scale` in float32 where given, as a frame's are read) against the true albedo on `mask`,
    after removing the true shading and fitting one gain (module docstring). In batches of pixels:
    CIEDE2000's dozens of temporaries over a megapixel would be gigabytes, and a float image of
    the whole estimate would be four times an 8-bit frame's bytes."""
    pixels = np.flatnonzero(mask.ravel())
    if len(pixels) == 0:
        return {"psnr_db": None, "rgb_rms": None, "delta_e2000": None}
    flat_estimate, flat_albedo = estimate.reshape(-1, 3), truth.albedo.reshape(-1, 3)
    flat_light = truth.white_irradiance.ravel()

    def batch(k: int) -> tuple[np.ndarray, np.ndarray]:
        part = pixels[k : k + _BATCH]
        read = flat_estimate[part] if full_scale is None else flat_estimate[part].astype(np.float32) / full_scale
        found = read.astype(np.float64) / flat_light[part][:, None]
        return found, flat_albedo[part].astype(np.float64)

    starts = range(0, len(pixels), _BATCH)
    cross = square = 0.0
    for k in starts:
        found, true = batch(k)
        cross += float((found * true).sum())
        square += float((found * found).sum())
    gain = cross / max(square, 1e-300)
    squared_error = total_e = 0.0
    for k in starts:
        found, true = batch(k)
        found = np.clip(found * gain, 0.0, 1.0)
        squared_error += float(((found - true) ** 2).sum())
        total_e += float(delta_e2000(lab(found), lab(true)).sum())
    mse = squared_error / (3 * len(pixels))
    return {
        "psnr_db": float(10 * np.log10(1.0 / max(mse, 1e-12))),
        "rgb_rms": float(np.sqrt(mse)),
        "delta_e2000": total_e / len(pixels),
    }


def lab(rgb: np.ndarray) -> np.ndarray:
    """CIE L*a*b* (D65) of linear RGB (N, 3) in [0, 1]."""
    xyz = rgb @ _SRGB_TO_XYZ.T / _D65
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.column_stack([116 * f[:, 1] - 16, 500 * (f[:, 0] - f[:, 1]), 200 * (f[:, 1] - f[:, 2])])


def delta_e2000(lab1: np.ndarray, lab2: np.ndarray) -> np.ndarray:
    """CIEDE2000 colour difference (Sharma, Wu and Dalal 2005) between L*a*b* rows, kL = kC = kH = 1."""
    l1, a1, b1 = lab1.T
    l2, a2, b2 = lab2.T
    c_mean = 0.5 * (np.hypot(a1, b1) + np.hypot(a2, b2))
    g = 0.5 * (1 - np.sqrt(c_mean**7 / (c_mean**7 + 25.0**7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1p, c2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    dl, dc = l2 - l1, c2p - c1p
    dh = h2p - h1p
    dh = np.where(dh > 180, dh - 360, np.where(dh < -180, dh + 360, dh))
    dh = np.where(c1p * c2p == 0, 0.0, dh)
    dh_big = 2 * np.sqrt(c1p * c2p) * np.sin(np.radians(dh / 2))
    l_mean, c_mean_p = 0.5 * (l1 + l2), 0.5 * (c1p + c2p)
    h_sum = h1p + h2p
    h_mean = np.where(np.abs(h1p - h2p) <= 180, h_sum / 2, np.where(h_sum < 360, (h_sum + 360) / 2, (h_sum - 360) / 2))
    h_mean = np.where(c1p * c2p == 0, h_sum, h_mean)
    t = (
        1
        - 0.17 * np.cos(np.radians(h_mean - 30))
        + 0.24 * np.cos(np.radians(2 * h_mean))
        + 0.32 * np.cos(np.radians(3 * h_mean + 6))
        - 0.20 * np.cos(np.radians(4 * h_mean - 63))
    )
    s_l = 1 + 0.015 * (l_mean - 50) ** 2 / np.sqrt(20 + (l_mean - 50) ** 2)
    s_c = 1 + 0.045 * c_mean_p
    s_h = 1 + 0.015 * c_mean_p * t
    r_c = 2 * np.sqrt(c_mean_p**7 / (c_mean_p**7 + 25.0**7))
    r_t = -np.sin(np.radians(2 * 30 * np.exp(-(((h_mean - 275) / 25) ** 2)))) * r_c
    return np.sqrt((dl / s_l) ** 2 + (dc / s_c) ** 2 + (dh_big / s_h) ** 2 + r_t * (dc / s_c) * (dh_big / s_h))
