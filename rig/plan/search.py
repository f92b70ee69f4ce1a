"""The fewest rings whose interpolated surface stays within a tolerance on every region of the
surface (the area-weighted quantile of its error) and covers it, by rehearsal on the pilot
(rig.plan.rehearsal): for non-uniform radii and, to compare, for evenly spaced ones.

Where the rings go (non-uniform): the interpolation error of a smooth patch between rings Delta
projector pixels apart is about a * kappa * (Delta / g)^2 (kappa the curvature across the rings, g
the rate in px per mm at which the ring radius grows along the surface; a = 1 / (2 sqrt(30)) for the
rms of a linear interpolant). Minimising the ring count for a given total squared error over the
surface gives, per radius bin b, Delta_b proportional to C_b^(-1/5) with C_b = sum over the bin's
surface samples of (kappa / g^2)^2 (a Lagrange multiplier; the fifth root keeps a few strongly bent
samples from deciding). How many rings: the scale of that profile is searched, each candidate
rehearsed, so the count fits the interpolant actually used and the places (a limb, an edge) that
no curvature model describes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rig.config import RingPlanSettings
from rig.pipeline import Interpolant
from rig.plan.rehearsal import PilotSurface, Rehearsal, rehearse
from rig.plan.ring_spacing import Demand, graded, place_rings

_SEARCH_STEPS = 9  # bisection steps over the profile's scale (and over the uniform count)


@dataclass(frozen=True)
class SearchResult:
    radii_px: list[float]
    rehearsal: Rehearsal
    met: bool  # whether any candidate met the tolerance and coverage (if not: the densest tried)
    tried: list[Rehearsal]


def rms_shape(demands: list[Demand], edges: np.ndarray, bin_px: float) -> np.ndarray:
    """Relative ring spacing per radius bin (smallest 1; inf where no surface sample lies)."""
    radius = np.concatenate([d.radius_px for d in demands])
    weight = np.concatenate([d.kappa_across / np.maximum(d.px_per_mm, 1e-9) ** 2 for d in demands]) ** 2
    which = np.clip(((radius - edges[0]) // bin_px).astype(np.int64), 0, len(edges) - 1)
    total = np.bincount(which, weight, len(edges))
    shape = np.full(len(edges), np.inf)
    shape[total > 0] = total[total > 0] ** -0.2
    finite = np.isfinite(shape)
    return shape / shape[finite].min() if finite.any() else np.ones(len(edges))


@dataclass(frozen=True, eq=False)
class Rehearser:
    """Rehearses ring sets on a pilot's views (rig.plan.rehearsal.rehearse) with one interpolant."""

    pilots: list[PilotSurface]
    center_px: tuple[float, float]
    method: Interpolant
    noise_mm: float
    quantile: float = 0.95
    on_rehearsal: Callable[[Rehearsal], None] | None = None  # each one told, for a progress display

    def __call__(self, radii: list[float]) -> Rehearsal:
        found = rehearse(self.pilots, np.asarray(radii), self.center_px, self.method, self.noise_mm, self.quantile)
        if self.on_rehearsal is not None:
            self.on_rehearsal(found)
        return found


def nonuniform_rings(
    trial: Rehearser,
    edges: np.ndarray,
    shape: np.ndarray,
    settings: RingPlanSettings,
    tolerance_mm: float,
    last_px: float = np.inf,
) -> SearchResult:
    """Bisection over the scale k of spacing clip(k * shape, min, max): the fewest rings rehearsed
    within the tolerance (none beyond `last_px`)."""

    def radii_for(scale: float) -> list[float]:
        profile = np.clip(scale * shape, settings.min_spacing_px, settings.max_spacing_px)
        return place_rings(edges, graded(profile, settings.bin_px), settings.bin_px, last_px)

    flattest = float(shape[np.isfinite(shape)].max())  # at the low end every bin with surface is densest
    low, high = math.log(settings.min_spacing_px / flattest), math.log(settings.max_spacing_px)
    return _bisect(lambda x: radii_for(math.exp(x)), trial, low, high, tolerance_mm, settings)


def uniform_count(trial: Rehearser, edges: np.ndarray, settings: RingPlanSettings, tolerance_mm: float) -> SearchResult:
    """The fewest evenly spaced rings over the same radii rehearsed within the tolerance."""
    start, end = float(edges[0]), float(edges[-1] + settings.bin_px)
    most = max(2, math.ceil((end - start) / settings.min_spacing_px) + 1)

    def radii_for(x: float) -> list[float]:
        count = round(most - x)  # x grows toward fewer rings, as the scale does above
        return [float(r) for r in np.linspace(start, end, max(2, count))]

    return _bisect(radii_for, trial, 0.0, float(most - 2), tolerance_mm, settings)


def _bisect(
    radii_for: Callable[[float], list[float]],
    trial: Callable[[list[float]], Rehearsal],
    low: float,
    high: float,
    tolerance_mm: float,
    settings: RingPlanSettings,
) -> SearchResult:
    """Largest x in [low, high] (fewer rings as x grows) whose rings rehearse within the tolerance,
    assuming the error grows with x, covering at least settings.min_coverage of the surface and
    settings.keep_coverage of what the densest rings cover; remembers every candidate and returns
    the fewest rings that met."""
    tried: list[Rehearsal] = []
    densest = radii_for(low)
    first = trial(densest)
    tried.append(first)
    if not first.meets(tolerance_mm, settings.min_coverage):
        return SearchResult(densest, first, False, tried)
    # fewer rings must not buy their error with holes
    least_covered = max(settings.min_coverage, settings.keep_coverage * first.covered)
    best = (densest, first)
    cache: dict[int, Rehearsal] = {len(densest): first}
    for _ in range(_SEARCH_STEPS):
        middle = 0.5 * (low + high)
        radii = radii_for(middle)
        result = cache.get(len(radii)) or trial(radii)
        cache[len(radii)] = result
        tried.append(result)
        if result.meets(tolerance_mm, least_covered):
            low = middle
            if len(radii) < len(best[0]):
                best = (radii, result)
        else:
            high = middle
    return SearchResult(best[0], best[1], True, tried)
