"""Where several projectors light the same surface, from the dissertation's intensity cue.

Under projected light alone, a surface lit by two projectors returns the sum of what each gives
it, so it is brighter than the brightest single projector makes it. From a dark frame, one frame
per projector lit alone and one with all lit together: the light beyond the brightest single
projector's share, if it is a real fraction of the total (`ratio`) and above the noise, marks
the overlap. The per-projector frames make it independent of the surface's albedo.
"""

from __future__ import annotations

import numpy as np

NOISE_FLOOR = 0.015  # of full scale: below this the excess light is noise
MIN_LIGHT = 0.03  # of full scale: darker pixels are unlit or shadowed
SATURATED = 0.98  # of full scale


def _mono(image: np.ndarray) -> np.ndarray:
    return (image.mean(axis=2) if image.ndim == 3 else image).astype(np.float32)


def overlap_from_cue(frames: list[np.ndarray], full_scale: int, ratio: float) -> np.ndarray:
    """Mask (H, W) of pixels lit by more than one projector. `frames`: dark, each projector alone,
    all together (as rig.pipeline.capture captures them)."""
    if len(frames) < 4:
        raise ValueError("the overlap cue needs a dark frame, two or more single frames and a together frame")
    mono = [_mono(f) for f in frames]
    dark, singles, together = mono[0], mono[1:-1], mono[-1]
    lit = [s - dark for s in singles]
    # Where the frame of all projectors clips, its sum is lost: add the single frames instead.
    clipped = together >= SATURATED * full_scale
    total = np.where(clipped, np.sum(lit, axis=0), together - dark)
    brightest = np.max(lit, axis=0)
    excess = total - brightest
    return (total > MIN_LIGHT * full_scale) & (excess > NOISE_FLOOR * full_scale) & (excess > ratio * total)


def precision_recall(found: np.ndarray, truth: np.ndarray, within: np.ndarray) -> tuple[float, float]:
    """Precision and recall of `found` against `truth`, over the pixels `within`."""
    f, t = found & within, truth & within
    hits = float((f & t).sum())
    return hits / max(1.0, float(f.sum())), hits / max(1.0, float(t.sum()))
