"""Light spilled from a bright neighbour is not a pixel's own: a camera pixel beside one many times
brighter (black rubber beside white paper, the dark side of a shadow's edge) receives through the
lens's blur part of the light that falls where the neighbour looks, with the neighbour's patterns,
and its own are drowned: a phase, a Gray edge or a ring edge read there lies toward the neighbour.
On the simulated dark-and-white box (50:1) HDR read the dark pixel beside an edge 0.5 mm off and
the next one 0.13 mm (medians), against 0.04 mm further in; the bright side's first pixel 0.13 mm
(kept: most of its light is its own).

Where the contrast (white frame less dark frame: a codec's first two frames, or the fringes' peak
and trough of cued_phase, which shows neither; Codec.references) among a
pixel and its 8 neighbours spans more than `SPILL_RATIO` from darkest to brightest, a pixel there
below `PLATEAU` of the brightest and more than `OWN` times the darkest is left out and counted
(`rejected_outshone`): the dark side's first pixel (so lit by spill that it looks half bright among
them), not the bright side's plateau, nor the dark pixel next in, whose light is still mostly its
own (HDR on the box: it read 12 % above the dark plateau beside a clipped neighbour, and keeping
such pixels took completeness from 94.8 to 97.2 % at rms 0.060 -> 0.065 mm, matte 0.049). A wider
blur makes a run of such steps, each caught in turn. The ratio does not depend on the exposure, so
HDR cannot read these pixels; dimming the bright side's patterns (adaptive projection) lowers it,
so that fewer are lost.

Off unless `scan.exposure.drop_outshone`: the ring planner's pilot leans on the shadow-edge pixels
it drops (on the staircase it then planned 26 rings for 0.2 mm instead of 32, and the surface
bridged the stairs' front edge).
"""

from __future__ import annotations

import cv2
import numpy as np

from rig.patterns.correspondence import Correspondence
from rig.patterns.saturation import without_pixels

SPILL_RATIO = 4.0  # an edge this strong (brightest to darkest of 3 x 3) drowns its dark side's first pixels
OWN = 1.25  # a pixel at most this far above its darkest neighbour keeps most of its light its own
PLATEAU = 0.7  # of the brightest nearby: the bright side, whose first pixel lost a little of its light


def outshone(white: np.ndarray, black: np.ndarray) -> np.ndarray:
    """(H, W) the pixels beside a strong edge in contrast (white less black; the mean of a colour
    frame's channels) that are not on its bright plateau (see the module docstring)."""
    contrast = _one_channel(white) - _one_channel(black)
    disc = np.ones((3, 3), np.uint8)
    brightest = cv2.dilate(contrast, disc)
    darkest = np.maximum(cv2.erode(contrast, disc), np.float32(0.0))
    return (brightest > SPILL_RATIO * darkest) & (contrast < PLATEAU * brightest) & (contrast > OWN * darkest)


def without_outshone(corr: Correspondence, white: np.ndarray, black: np.ndarray) -> Correspondence:
    """`corr` without the pixels outshone by a neighbour (see the module docstring)."""
    return without_pixels(corr, outshone(white, black), "rejected_outshone")


def _one_channel(frame: np.ndarray) -> np.ndarray:
    frame = frame.astype(np.float32, copy=False)
    return frame.mean(axis=2, dtype=np.float32) if frame.ndim == 3 else frame


class SpillScreen:
    """The white and dark frames of a stream kept as they arrive (frames 0 and 1), to leave out
    the outshone pixels when it finishes."""

    def __init__(self) -> None:
        self._white: np.ndarray | None = None
        self._black: np.ndarray | None = None

    def add(self, index: int, frame: np.ndarray) -> None:
        if index == 0:
            self._white = _one_channel(frame).copy()
        elif index == 1:
            self._black = _one_channel(frame).copy()

    def honoured(self, corr: Correspondence) -> Correspondence:
        if self._white is None or self._black is None:
            return corr
        return without_outshone(corr, self._white, self._black)
