"""Where an intensity mask steps (rig.pipeline.projection_mask: bright dark paint beside a dimmed
white), the projector's lens blurs each pattern across the step, and a camera pixel near it sees
its neighbours' patterns weighted by their light: the brighter side's lean in. A phase, a Gray edge
or a ring edge read there lies toward the undimmed side. On the simulated dark-and-white box it
was a third of a projector pixel on the first pixels either side of a step, 0.3 mm and more.

The lean is foretold from the mask: a Gaussian blur of the light the mask lets through, and the
centre of that light about each projector pixel (along the coded direction) less the pixel itself.
The blur is the projector's and is not on any data sheet, so it is measured on the scan itself:
where the pre-scan (unmasked, nothing to lean) gave a camera pixel its own point, the masked
decode's coordinate less the pre-scan's is the lean; the blur whose foretold lean is nearest
(median) over the pixels near a step is taken. Each decoded coordinate then has its lean taken
off (a few fixed-point steps: the lean is foretold at the true coordinate), and a pixel whose lean
exceeds `max_shift_px` is left out (`rejected_mask_edge`): there the light is mostly a neighbour's,
and the foretelling too coarse to trust. Sparse codecs (rings) keep their sub-pixel samples as
decoded; the pixels they lie between are left out where the lean passes the bound, with the blur
at `fallback_blur_px`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from rig.patterns import Correspondence, without_pixels

BLURS_PX = np.round(np.arange(0.2, 1.55, 0.05), 2)  # the projector blurs tried (Gaussian sigma, projector pixels)
NEAR_STEP_PX = 0.05  # a pixel whose lean at the widest blur tried passes this lies near a step
MIN_NEAR = 200  # fewer pixels near a step than this: the blur is not measured (fallback_blur_px)
FIXED_POINT_STEPS = 3
AXES = {"u": 1, "v": 0}  # a coordinate and the projector image axis it runs along


def lean(light: np.ndarray, blur_px: float, axis: int) -> np.ndarray:
    """(h, w) how far (projector pixels, along `axis`) the blurred light about each projector pixel
    centres away from it (see the module docstring)."""
    pad = int(np.ceil(4 * blur_px)) + 1  # the light beyond the image as at its edge, where it is
    light = np.pad(light.astype(np.float32, copy=False), pad, mode="edge")
    positions = np.arange(-pad, light.shape[axis] - pad, dtype=np.float32)
    position = positions[None, :] if axis == 1 else positions[:, None]
    blurred = cv2.GaussianBlur(light, (0, 0), blur_px, borderType=cv2.BORDER_REPLICATE)
    moment = cv2.GaussianBlur(light * position, (0, 0), blur_px, borderType=cv2.BORDER_REPLICATE)
    shift = moment / np.maximum(blurred, np.float32(1e-12)) - position
    return shift[pad:-pad, pad:-pad]


def sampled(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """`image` (projector pixels) bilinearly at columns `u`, rows `v` (any shape; 0 outside)."""
    coordinates = np.stack([np.ravel(v), np.ravel(u)])
    return ndimage.map_coordinates(image, coordinates, order=1, mode="constant", cval=0.0).reshape(np.shape(u))


@dataclass(frozen=True)
class Unleaned:
    """A decode with a mask's lean taken off (MaskSkew.applied): the Correspondence, the blur
    measured (None where it could not be: fallback_blur_px was used), and `lean_px` (H, W): how far
    the mask leaned each pixel (projector pixels, the most along any coded axis; 0 where the
    pre-scan did not map it), which says how near a step of the mask it was read."""

    corr: Correspondence
    blur_px: float | None
    lean_px: np.ndarray

    @classmethod
    def unmasked(cls, corr: Correspondence) -> Unleaned:
        """A decode no mask leaned."""
        return cls(corr, None, np.zeros(corr.valid.shape))


@dataclass(frozen=True)
class MaskSkew:
    """One (projector, camera) pair's mask and pre-scan map, to take the mask's lean off a decode.
    `light`: (h, w) the share of light the mask lets through; `u`, `v`: (H, W) the projector pixel
    each camera pixel lights (NaN where unknown); `own`: the camera pixels the pre-scan gave a
    point of their own (the rest of the map is a neighbour's)."""

    light: np.ndarray
    u: np.ndarray
    v: np.ndarray
    own: np.ndarray
    max_shift_px: float
    fallback_blur_px: float

    def blur_px(self, corr: Correspondence) -> float | None:
        """The projector blur that best foretells how far `corr`'s coordinates moved from the
        pre-scan's near the mask's steps (every other blur tried, then the two beside the best);
        None where too few pixels lie near one."""
        near_steps = []  # per coded axis: (axis, observed lean, projector columns, rows)
        for name, axis in AXES.items():
            decoded = getattr(corr, name)
            if decoded is None:
                continue
            mapped = self.u if name == "u" else self.v
            use = self.own & corr.valid & np.isfinite(decoded) & np.isfinite(self.u) & np.isfinite(self.v)
            u, v = self.u[use], self.v[use]
            near = np.abs(sampled(lean(self.light, float(BLURS_PX[-1]), axis), u, v)) > NEAR_STEP_PX
            near_steps.append((axis, (decoded[use] - mapped[use])[near], u[near], v[near]))
        if sum(len(observed) for _, observed, _, _ in near_steps) < MIN_NEAR:
            return None
        misses: dict[int, float] = {}

        def miss(i: int) -> float:
            if i not in misses:
                blur = float(BLURS_PX[i])
                off = [observed - sampled(lean(self.light, blur, axis), u, v) for axis, observed, u, v in near_steps]
                misses[i] = float(np.median(np.abs(np.concatenate(off))))
            return misses[i]

        best = min(range(0, len(BLURS_PX), 2), key=miss)
        return float(BLURS_PX[min((i for i in (best - 1, best, best + 1) if 0 <= i < len(BLURS_PX)), key=miss)])

    def applied(self, corr: Correspondence) -> Unleaned:
        """`corr` with the mask's lean taken off its coordinates and the pixels leaning too far left
        out (see Unleaned)."""
        measured = self.blur_px(corr)
        blur = self.fallback_blur_px if measured is None else measured
        coded = [name for name in AXES if getattr(corr, name) is not None]
        leans = {name: lean(self.light, blur, AXES[name]) for name in (coded or AXES)}
        lean_px = np.zeros(corr.valid.shape)
        if not coded:  # sparse samples: their pixels' lean where the pre-scan mapped them
            mapped = np.isfinite(self.u) & np.isfinite(self.v)
            u, v = self.u[mapped], self.v[mapped]
            lean_px[mapped] = np.max([np.abs(sampled(s, u, v)) for s in leans.values()], axis=0)
            return Unleaned(without_pixels(corr, lean_px > self.max_shift_px, "rejected_mask_edge"), None, lean_px)
        decoded = {name: getattr(corr, name) for name in coded}
        fixed = corr.valid & np.logical_and.reduce([np.isfinite(c) for c in decoded.values()])
        fixed &= np.isfinite(self.u) & np.isfinite(self.v)  # steps lie only where the pre-scan mapped
        start = {"u": self.u[fixed], "v": self.v[fixed], **{name: c[fixed] for name, c in decoded.items()}}
        true = dict(start)
        shifts = {name: np.zeros(int(fixed.sum())) for name in coded}
        for _ in range(FIXED_POINT_STEPS):
            shifts = {name: sampled(leans[name], true["u"], true["v"]) for name in coded}
            true = {**true, **{name: start[name] - shifts[name] for name in coded}}
        replaced = {}
        for name, coordinate in decoded.items():
            moved = coordinate.copy()
            moved[fixed] = true[name]
            replaced[name] = moved
        corr = dataclasses.replace(corr, **replaced)
        lean_px[fixed] = np.max([np.abs(s) for s in shifts.values()], axis=0)
        return Unleaned(without_pixels(corr, lean_px > self.max_shift_px, "rejected_mask_edge"), measured, lean_px)


def unleaned(corr: Correspondence, per_pass: list[MaskSkew], k: int) -> Unleaned:
    """Pass `k`'s decode with its masks' lean taken off: `per_pass` holds a MaskSkew for each
    pass's masks (one for every pass where they are the same, as in an HDR bracket; none without
    masks, the decode as it is)."""
    return per_pass[min(k, len(per_pass) - 1)].applied(corr) if per_pass else Unleaned.unmasked(corr)
