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
ROWS_AT_ONCE = 32  # camera rows per chunk: candidates x frequencies x pixels stay small


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
    was clear, per pixel."""
    first, others = periods[0], np.asarray(periods[1:], dtype=np.float32)
    count = math.ceil(pixels / first) + 1
    start = np.float32(math.radians(start_deg))
    x = np.full(fraction.shape, np.nan, dtype=np.float32)
    clear = np.zeros(fraction.shape, dtype=bool)
    candidates = np.arange(-1, count, dtype=np.float32)  # -1: the half pixel before the first centre
    for top in range(0, fraction.shape[0], ROWS_AT_ONCE):
        rows = slice(top, top + ROWS_AT_ONCE)
        scale = np.maximum(amplitude[rows], np.float32(1e-6))
        readings = np.stack([np.clip((s[rows] - offset[rows]) / scale, -1.0, 1.0) for s in singles], axis=-1)
        places = (candidates + fraction[rows][..., None]) * np.float32(first)  # (h, w, count)
        predicted = np.cos(np.float32(2 * np.pi) * places[..., None] / others + start)  # (h, w, count, F - 1)
        distance = np.sqrt(((predicted - readings[..., None, :]) ** 2).mean(axis=-1))
        inside = (places > -0.5) & (places < pixels - 0.5)
        distance = np.where(inside, distance, np.inf)  # beyond the projector: no candidate
        order = np.argsort(distance, axis=-1)
        best = np.take_along_axis(distance, order[..., :1], axis=-1)[..., 0]
        second = np.take_along_axis(distance, order[..., 1:2], axis=-1)[..., 0]
        x[rows] = np.take_along_axis(places, order[..., :1], axis=-1)[..., 0]
        clear[rows] = (best <= MICRO_RESIDUAL) & (best <= MICRO_AMBIGUITY * second)
    return x, clear
