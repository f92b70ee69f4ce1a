"""Adaptive projection in two passes at one exposure. Where a mask steps (a bright surface dimmed
beside a dark one left at full light), the projector's blur lends each side's patterns to the
other's first pixels (rig.pipeline.mask_skew), so one pass loses a band of pixels at every step
across the coded direction: on the simulated dark-and-white box, 3 to 4 camera pixels at each
checker edge, 6 % of the surface. Moving the step to the other side of the edge reads them:

- pass one: each mask's dimming spread `SPREAD_PX` further onto the dark side, so the step lies in
  the dark paint and the bright side's first pixels read their own dimmed patterns;
- pass two: the dimming pulled back off the dark side and a projector pixel into the bright one,
  so the dark side's first pixels are lit at full light with no step near them (the bright side's
  edge clips there, and pass one has read it).

Both passes are taken at the scan's exposure, each decode has its own masks' lean taken off, and
per pixel the passes that read it from as far from a step as the best one count, their coordinates
averaged (rig.pipeline.pass_merge.merge_mask_passes): a pixel far from every step is read twice.

The second pass is taken only where it pays (`step_band` against `MaskSettings.second_pass_share`):
the share of the lit projector pixels about the masks' steps that one pass would lose, foretold
from the masks and the pre-scan's map before any pattern is shown, along the directions the codec
codes. On the simulated bench (phase, coding columns): 6.9 % on the dark-and-white box, 5.0 % on the
machined steps (two passes: 99.2 to 99.7 % complete), none on the glossy sphere, whose one highlight
is dimmed smoothly.
"""

from __future__ import annotations

import cv2
import numpy as np

from rig.pipeline.mask_skew import AXES, lean

SPREAD_PX = 1  # pass one: the dimming spread this much further onto the dark side


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def two_pass_masks(masks: list[np.ndarray], margin_px: int) -> list[list[np.ndarray]]:
    """From one pass's masks (levels, each projector's, spread `margin_px` about each dimmed pixel):
    the two passes' (see the module docstring)."""
    spread = [cv2.erode(mask, _disc(SPREAD_PX)) for mask in masks]
    pulled_back = [cv2.dilate(mask, _disc(margin_px + 1)) for mask in masks]
    return [spread, pulled_back]


def step_band(
    light: np.ndarray, u: np.ndarray, v: np.ndarray, max_shift_px: float, blur_px: float, axes: str = "uv"
) -> float:
    """The share of the projector pixels lighting the camera pixels the pre-scan mapped (columns
    `u`, rows `v`) where one pass with `light` (the mask's share of light per projector pixel)
    would lean a decode of the coded `axes` past `max_shift_px` at the projector blur `blur_px`:
    the band about its steps. Counted on the projector, since the dark side of a step (unread at
    the pre-scan's short exposure) has no map of its own; each such projector pixel costs a camera
    pixel or more on either side of the step."""
    mapped = np.isfinite(u) & np.isfinite(v)
    height, width = light.shape
    cols, rows = np.rint(u[mapped]).astype(np.int64), np.rint(v[mapped]).astype(np.int64)
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    lit = np.zeros(light.shape, np.uint8)
    lit[rows[inside], cols[inside]] = 1
    lit = cv2.dilate(lit, _disc(1)).astype(bool)  # the gaps between mapped camera pixels closed
    if not lit.any():
        return 0.0
    leaning = np.max([np.abs(lean(light, blur_px, AXES[axis])) for axis in axes], axis=0) > max_shift_px
    return float(leaning[lit].mean())
