"""Saturation is never a point: a camera pixel at full scale in any frame it decodes from says
nothing of where the pattern's edge or phase lies there (the sensor clipped it), so every codec's
correspondence leaves it out and counts it (`rejected_saturated`).

A saturated pixel in the white frame may still read a Gray bit right (the pattern and its inverse
differ), but a clipped phase step is biased, a clipped ring edge moves, and a pixel that clips in
one exposure is the one another exposure (HDR) reads: the rule is one rule for every codec.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rig.patterns.correspondence import Correspondence, RingSamples

_SATURATED = "rejected_saturated"  # the count of pixels (or ring samples) saturation drops


class SaturationMask:
    """The pixels at full scale in any frame added so far (any channel of a colour frame), kept as
    each pixel's brightest value so far: one pass over each frame, in place (a comparison and an
    or allocated and passed over each frame twice: 1.08 ms a 5 MP frame, against 0.42); whether any
    pixel clipped is one pass over those values, and the mask is made only when asked for."""

    def __init__(self, full_scale: int) -> None:
        self.full_scale = full_scale
        self._peak: np.ndarray | None = None
        self._mask: np.ndarray | None = None
        self._clipped: bool | None = None

    def add(self, frame: np.ndarray) -> None:
        if self._peak is None:
            self._peak = frame.copy()
        else:
            np.maximum(self._peak, frame, out=self._peak)
        self._mask, self._clipped = None, None

    @property
    def mask(self) -> np.ndarray | None:
        """(H, W) the pixels at full scale in any frame so far; None before the first."""
        if self._mask is None and self._peak is not None:
            clipped = self._peak >= self.full_scale
            self._mask = clipped.any(axis=2) if clipped.ndim == 3 else clipped
        return self._mask

    @property
    def clipped(self) -> bool:
        """Whether any pixel reached full scale in a frame so far: the brightest value alone, read
        in one pass, where the mask is an image made and read (a 12 MP frame's: 3 ms)."""
        if self._clipped is None:
            peak = self._peak
            self._clipped = peak is not None and peak.size > 0 and bool(peak.max() >= self.full_scale)
        return self._clipped

    def honoured(self, corr: Correspondence) -> Correspondence:
        """`corr` without the saturated pixels (see the module docstring)."""
        if self._peak is None:
            return corr
        return without_saturated(corr, self.mask) if self.clipped else _none_dropped(corr, _SATURATED)


def saturated_in(frames: list[np.ndarray], full_scale: int) -> np.ndarray | None:
    """(H, W) the pixels at full scale in any of `frames`, None for no frames."""
    mask = SaturationMask(full_scale)
    for frame in frames:
        mask.add(frame)
    return mask.mask


def without_saturated(corr: Correspondence, saturated: np.ndarray) -> Correspondence:
    """`corr` without the pixels of `saturated` (without_pixels, counted as `rejected_saturated`),
    which it also records in `extra["saturated"]` for HDR's merge."""
    corr = without_pixels(corr, saturated, _SATURATED)
    if not saturated.any():
        return corr
    extra = {**corr.extra, "saturated": saturated | corr.extra.get("saturated", False)}
    return dataclasses.replace(corr, extra=extra)


def without_pixels(corr: Correspondence, unread: np.ndarray, counter: str) -> Correspondence:
    """`corr` with every pixel of `unread` (H, W) invalid, its coordinates NaN, and the ring
    samples between two pixels of which either is unread dropped; `counts[counter]` the pixels (or
    samples) so dropped. Applying it twice drops nothing more (and counts the first)."""
    if not unread.any():
        return _none_dropped(corr, counter)
    counts = dict(corr.counts)
    counts[counter] = counts.get(counter, 0) + int(np.count_nonzero(corr.valid & unread))
    u = None if corr.u is None else np.where(unread, np.nan, corr.u).astype(corr.u.dtype, copy=False)
    v = None if corr.v is None else np.where(unread, np.nan, corr.v).astype(corr.v.dtype, copy=False)
    samples = corr.samples
    if samples is not None:
        clear = ~_touches(samples, unread)
        counts[counter] += int((~clear).sum())
        samples = subset_samples(samples, clear)
        if "ring_samples" in counts:
            counts["ring_samples"] = len(samples)
    return dataclasses.replace(corr, valid=corr.valid & ~unread, u=u, v=v, samples=samples, counts=counts)


def _none_dropped(corr: Correspondence, counter: str) -> Correspondence:
    """without_pixels with no pixel to drop: `counts[counter]` as it was, or 0."""
    return dataclasses.replace(corr, counts={**corr.counts, counter: corr.counts.get(counter, 0)})


def _touches(samples: RingSamples, unread: np.ndarray) -> np.ndarray:
    """(M,) whether either camera pixel a sample lies between is unread."""
    height, width = unread.shape
    x, y = samples.camera_xy[:, 0], samples.camera_xy[:, 1]
    touched = np.zeros(len(samples), dtype=bool)
    for cols, rows in ((np.floor(x), np.floor(y)), (np.ceil(x), np.ceil(y))):
        c = np.clip(cols.astype(np.int64), 0, width - 1)
        r = np.clip(rows.astype(np.int64), 0, height - 1)
        touched |= unread[r, c]
    return touched


def subset_samples(samples: RingSamples, keep: np.ndarray) -> RingSamples:
    """The samples `keep` marks, with every per-sample array cut alike."""
    per_sample = {
        f.name: getattr(samples, f.name)[keep]
        for f in dataclasses.fields(samples)
        if isinstance(getattr(samples, f.name), np.ndarray) and f.name != "ring_radii_px"
    }
    return dataclasses.replace(samples, **per_sample)
