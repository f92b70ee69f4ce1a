"""Merging the passes of one pair's scan, per pixel: the exposures of an HDR bracket
(merge_exposures) and the passes of adaptive projection under different masks (merge_mask_passes).

At each pixel the HDR merge takes the exposure that reads it best: the one whose decode is valid
there with the highest quality (the codec's modulation or contrast, in fractions of full scale: it
grows with the exposure until the pixel clips, and a clipped pixel is no longer valid). A dark
rubber part is read at the longest exposure, a machined highlight at the shortest, the rest in
between. Ring samples are kept from the exposure their pixel takes (a ring edge is read once, not
once per exposure), and the coarse bands every pixel read with them. Works for every codec, since
each exposure's Correspondence is the codec's own.

Mask passes (rig.pipeline.mask_passes) are all at one exposure: at each pixel, the passes that read
it from as far from a step of their masks as the best one count, and their coordinates are
averaged, weighted by quality squared (a phase's noise goes as one over its modulation).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rig.patterns import Correspondence, RingSamples, subset_samples
from rig.pipeline.mask_skew import Unleaned

LEAN_TIE_PX = 0.02  # mask passes whose lean at a pixel is within this of the least all read it


def merge_passes(passes: list[Unleaned], under_masks: bool) -> Correspondence:
    """One pair's passes merged: one as it is; passes under different masks (`under_masks`) by
    merge_mask_passes; the exposures of a bracket by merge_exposures."""
    corrs = [one.corr for one in passes]
    if len(corrs) == 1:
        return corrs[0]
    if under_masks:
        return merge_mask_passes(corrs, [one.lean_px for one in passes])
    return merge_exposures(corrs, len(corrs) - 1)


def merge_exposures(
    corrs: list[Correspondence], reference: int, score: np.ndarray | None = None, counter: str = "hdr_exposures"
) -> Correspondence:
    """One Correspondence from the same pair's at several exposures (see the module docstring);
    the texture and what is not per pixel from `reference`'s. `score` (passes, H, W): what ranks
    the passes at each pixel, -inf where one did not read it (by default each pass's quality where
    it is valid); `counter`: the count that says how many passes were merged."""
    if score is None:
        score = np.stack([np.where(c.valid | _is_sparse(c), c.quality, -np.inf) for c in corrs])
    if any(_is_sparse(c) for c in corrs):
        score[np.stack([c.extra.get("saturated", np.zeros_like(c.valid)) for c in corrs])] = -np.inf
    best = np.argmax(score, axis=0)
    rows, cols = np.indices(best.shape)
    base = corrs[reference]

    def pick(arrays: list[np.ndarray]) -> np.ndarray:
        return np.stack(arrays)[best, rows, cols]

    valid = pick([c.valid for c in corrs]) if not _is_sparse(base) else np.zeros_like(base.valid)
    u = None if base.u is None else pick([c.u for c in corrs if c.u is not None])
    v = None if base.v is None else pick([c.v for c in corrs if c.v is not None])
    extra = {
        name: pick([c.extra[name] for c in corrs]) if array.shape == best.shape else array
        for name, array in base.extra.items()
        if name != "saturated"
    }
    extra["saturated"] = np.logical_and.reduce([c.extra.get("saturated", np.zeros_like(c.valid)) for c in corrs])
    samples = _merged_samples(corrs, best)
    if samples is not None:
        nearest = np.rint(samples.camera_xy).astype(np.int64)
        valid[nearest[:, 1], nearest[:, 0]] = True
    counts = {
        **base.counts,
        "decoded": int(valid.sum()),
        counter: len(corrs),
        # what no exposure read for clipping; each exposure's own count is its share of the bracket
        "rejected_saturated": int(extra["saturated"].sum()),
        "rejected_saturated_per_exposure": sum(c.counts.get("rejected_saturated", 0) for c in corrs),
    }
    if samples is not None:
        counts["ring_samples"] = len(samples)
    quality = pick([c.quality for c in corrs])
    return dataclasses.replace(
        base, valid=valid, quality=quality, u=u, v=v, extra=extra, counts=counts, samples=samples
    )


def _is_sparse(corr: Correspondence) -> bool:
    return corr.samples is not None


def _merged_samples(corrs: list[Correspondence], best: np.ndarray) -> RingSamples | None:
    """The ring samples of each exposure whose pixel that exposure reads best, all together."""
    kept = []
    for e, corr in enumerate(corrs):
        if corr.samples is None:
            return None
        nearest = np.rint(corr.samples.camera_xy).astype(np.int64)
        rows = np.clip(nearest[:, 1], 0, best.shape[0] - 1)
        cols = np.clip(nearest[:, 0], 0, best.shape[1] - 1)
        kept.append(subset_samples(corr.samples, best[rows, cols] == e))
    first = kept[0]
    joined = {
        f.name: np.concatenate([getattr(s, f.name) for s in kept])
        for f in dataclasses.fields(first)
        if isinstance(getattr(first, f.name), np.ndarray) and f.name != "ring_radii_px"
    }
    return dataclasses.replace(first, **joined)


def merge_mask_passes(corrs: list[Correspondence], leans: list[np.ndarray]) -> Correspondence:
    """One Correspondence from the same pair's passes under different masks (`leans`: each pass's
    lean per pixel, MaskSkew.applied), as the module docstring says; what is not per pixel from
    the first pass's."""
    readable = np.stack([_readable(c) for c in corrs])
    lean_px = np.stack(leans)
    least = np.min(np.where(readable, lean_px, np.inf), axis=0)
    counted = readable & (lean_px <= least + LEAN_TIE_PX)
    score = np.where(counted, np.stack([c.quality for c in corrs]).astype(np.float64), -np.inf)
    merged = merge_exposures(corrs, 0, score=score, counter="mask_passes")
    averaged = {}
    for name in ("u", "v"):
        picked = getattr(merged, name)
        if picked is None:
            continue
        coordinates = np.stack([getattr(c, name) for c in corrs]).astype(np.float64)
        weights = np.where(counted & np.isfinite(coordinates), np.square(np.where(counted, score, 0.0)), 0.0)
        total = weights.sum(axis=0)
        twice = (np.count_nonzero(weights, axis=0) > 1) & (total > 0)
        mean = np.einsum("kij,kij->ij", weights, np.nan_to_num(coordinates)) / np.where(twice, total, 1.0)
        averaged[name] = np.where(twice, mean, picked).astype(picked.dtype, copy=False)
    return dataclasses.replace(merged, **averaged)


def _readable(corr: Correspondence) -> np.ndarray:
    """(H, W) where a pass read the pixel: its valid pixels; for ring samples, every unclipped one."""
    if corr.samples is None:
        return corr.valid
    return ~corr.extra.get("saturated", np.zeros_like(corr.valid))
