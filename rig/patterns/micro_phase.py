"""Micro phase shifting (Gupta & Nayar, CVPR 2012), decoded: periods in a narrow band, the first
shown N >= 3 times shifted, every other once. The first gives the pixel's phase, offset and
amplitude; each single frame then reads cos(2 pi x / P_f + start) = (I_f - offset) / amplitude (the
band is narrow, so every period keeps about the same amplitude through the optics). Of the
projector coordinates the first phase allows, x_k = (k + fraction) P_1, the pixel takes the one
whose predicted cosines are nearest its readings (a nearest-neighbour search over the candidates),
and is dropped where the nearest is not clearly nearer than the next (MICRO_AMBIGUITY) or too far
from its readings (MICRO_RESIDUAL)."""

from __future__ import annotations

import math

import numpy as np

MICRO_RESIDUAL = 0.35  # rms distance of the readings from the chosen column's cosines, in amplitudes
MICRO_AMBIGUITY = 0.6  # the nearest candidate's distance over the next one's, at most
ROWS_AT_ONCE = 64  # camera rows per chunk: candidates x pixels stay small


def micro_unwrapped(
    fraction: np.ndarray,
    offset: np.ndarray,
    amplitude: np.ndarray,
    singles: list[np.ndarray],
    periods: list[float],
    start_deg: float,
    pixels: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The coordinate (from the first period's phase and the chosen count) and whether the choice
    was clear, per pixel. Candidate k predicts cos(a_fk + b_f) = C_fk cos b_f - S_fk sin b_f for
    period f (a_fk = 2 pi k P_1 / P_f, b_f the pixel's own phase there), so every candidate's
    squared distance from the readings is one matrix product of per-pixel terms with constants."""
    first, others = periods[0], np.asarray(periods[1:], dtype=np.float64)
    counts = np.arange(-1, math.ceil(pixels / first) + 1)  # -1: the half pixel before the first centre
    angles = 2 * np.pi * counts[None, :] * first / others[:, None]  # (F - 1, candidates)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    weights = np.concatenate([cos_a**2, sin_a**2, -2 * cos_a * sin_a, -2 * cos_a, 2 * sin_a]).astype(np.float32)
    shifts = (2 * np.pi * first / others).astype(np.float32)
    start = np.float32(math.radians(start_deg))
    x = np.full(fraction.shape, np.nan, dtype=np.float32)
    clear = np.zeros(fraction.shape, dtype=bool)
    for top in range(0, fraction.shape[0], ROWS_AT_ONCE):
        rows = slice(top, top + ROWS_AT_ONCE)
        scale = np.maximum(amplitude[rows], np.float32(1e-6))
        readings = np.stack([np.clip((s[rows] - offset[rows]) / scale, -1.0, 1.0) for s in singles], axis=-1)
        own = fraction[rows][..., None] * shifts + start  # b_f: (h, w, F - 1)
        cb, sb = np.cos(own), np.sin(own)
        terms = np.concatenate([cb * cb, sb * sb, cb * sb, readings * cb, readings * sb], axis=-1)
        squared = terms @ weights + (readings * readings).sum(axis=-1, keepdims=True)  # (h, w, candidates)
        places = (counts.astype(np.float32) + fraction[rows][..., None]) * np.float32(first)
        squared[(places <= -0.5) | (places >= pixels - 0.5)] = np.inf  # beyond the projector: no candidate
        nearest = np.argmin(squared, axis=-1)
        two = np.maximum(np.partition(squared, 1, axis=-1)[..., :2], 0.0)  # the nearest two (rounding: >= 0)
        best = np.sqrt(two.min(axis=-1) / np.float32(len(others)))
        second = np.sqrt(two.max(axis=-1) / np.float32(len(others)))
        x[rows] = np.take_along_axis(places, nearest[..., None], axis=-1)[..., 0]
        clear[rows] = (best <= MICRO_RESIDUAL) & (best <= MICRO_AMBIGUITY * second)
    return x, clear
