"""Ring planning (dissertation ch.4): the fewest rings that still represent a surface, from a pilot
scan's curvature.

Two criteria, both reported:
- **interpolation error (sagitta)**: between two rings Delta mm apart on a surface of normal
  curvature kappa across them, linear interpolation errs by up to kappa * Delta^2 / 8, so rings may
  be at most sqrt(8 e_tol / kappa) apart there. In projector pixels that spacing is Delta times the
  rate at which the ring radius grows along the surface (|grad_s R|, px per mm): small where the
  surface turns away from the projector, so rings crowd there. The uniform set takes the smallest
  spacing anywhere; the planned set (non-uniform radii) is placed greedily from the inside out,
  each spacing the smallest any radius in it allows, which is the fewest rings under the bound.
- **curvature frequency (Lee & Krim 2017)**: the pilot is cut into N dense rings; the curvature of
  each ring's 3D curve against arc length has a band limit f_max (the frequency under which
  `energy_fraction` of its spectral energy lies); Nyquist asks for rings 1 / (2 f_max) apart, a
  fraction f_s = 2 f_max / (the dense rings per mm) of the dense set: N_min = ceil(N * f_s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.config import RingPlanSettings
from rig.errors import PlanError
from rig.geometry import CameraModel, SurfaceCurvature, curve_curvature, principal_curvatures

# Numerical step for the radius gradient (mm).
_STEP_MM = 0.05
GRADE = 0.5  # ring spacing grows by at most this many px per px of radius (graded)


@dataclass(frozen=True, eq=False)
class PilotView:
    """What a pilot scan saw lit by one projector: world points (mm), that projector's model, and
    the centre of the camera that saw them (normals face it)."""

    points: np.ndarray
    projector: CameraModel
    viewpoint: np.ndarray
    camera: CameraModel | None = None  # with it, the plan is rehearsed on the pilot (rig.plan.rehearsal)
    grid: np.ndarray | None = None  # (H, W, 3) the points on the camera's pixels, when known


@dataclass(frozen=True, eq=False)
class Demand:
    """Per curvature sample of a pilot: its ring radius, the spacing the tolerance allows there (px)
    and the curvature across the rings (1/mm)."""

    radius_px: np.ndarray
    allowed_px: np.ndarray
    kappa_across: np.ndarray
    px_per_mm: np.ndarray  # |grad_s R|: how fast the ring radius grows along the surface


def minimum_rings(dense_rings: int, sampling_fraction: float) -> int:
    """The dissertation's N_min = ceil(N * f_s), N the dense (initial) ring count and f_s the
    sampling rate as a fraction of it (Table 1 of Lee & Krim 2017 is this relation, row by row)."""
    if dense_rings < 1 or not 0.0 <= sampling_fraction <= 1.0:
        raise PlanError(f"N_min needs N >= 1 and 0 <= f_s <= 1, got N={dense_rings}, f_s={sampling_fraction}")
    return max(1, math.ceil(dense_rings * sampling_fraction - 1e-9))  # 0.3 * 90 is 27.000000000000004


def ring_polar(projector: CameraModel, points: np.ndarray, center_px: tuple[float, float]) -> tuple[np.ndarray, ...]:
    """Ring radius and polar angle (projector pixels, radians) of world points, and whether they fall
    in front of the projector and inside its image."""
    uv, z = projector.project(points)
    du, dv = uv[:, 0] - center_px[0], uv[:, 1] - center_px[1]
    inside = (z > 0) & (uv[:, 0] >= -0.5) & (uv[:, 0] < projector.width - 0.5)
    inside &= (uv[:, 1] >= -0.5) & (uv[:, 1] < projector.height - 0.5)
    return np.hypot(du, dv), np.arctan2(dv, du), inside


def radius_gradient(projector: CameraModel, points: np.ndarray, center_px: tuple[float, float]) -> np.ndarray:
    """d(ring radius)/d(point), px per mm, (N, 3), by central differences."""
    grad = np.zeros_like(points)
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = _STEP_MM
        plus = ring_polar(projector, points + step, center_px)[0]
        minus = ring_polar(projector, points - step, center_px)[0]
        grad[:, axis] = (plus - minus) / (2 * _STEP_MM)
    return grad


def demand(
    view: PilotView, curvature: SurfaceCurvature, tolerance_mm: float, center_px: tuple[float, float], max_px: float
) -> Demand:
    """The ring spacing each smooth curvature sample allows under the sagitta bound. Samples whose
    quadric fits badly (a depth edge inside the fit: residual over 3 times the median) or that the
    projector does not light are left out: no spacing of rings mends an edge."""
    radius, _, inside = ring_polar(view.projector, curvature.points, center_px)
    smooth = curvature.valid & inside
    if smooth.any():
        smooth &= curvature.residual_mm <= 3.0 * np.median(curvature.residual_mm[smooth]) + 1e-6
    idx = np.flatnonzero(smooth)
    grad = radius_gradient(view.projector, curvature.points[idx], center_px)
    normal = curvature.normals[idx]
    across = grad - np.einsum("ij,ij->i", grad, normal)[:, None] * normal
    rate = np.linalg.norm(across, axis=1)
    kappa = np.abs(curvature.subset(idx).normal_curvature(across))
    allowed_mm = np.sqrt(8.0 * tolerance_mm / np.maximum(kappa, 1e-12))
    allowed = np.minimum(allowed_mm * rate, max_px)
    return Demand(radius[idx], allowed, kappa, rate)


def spacing_profile(demands: list[Demand], settings: RingPlanSettings) -> tuple[np.ndarray, np.ndarray]:
    """Radius bins (lower edges, px) over the radii the pilot saw, and the spacing each allows: the
    `demand_quantile` of its samples' demands (a few samples on an edge must not decide), empty bins
    borrowing from their neighbours."""
    radius = np.concatenate([d.radius_px for d in demands])
    allowed = np.concatenate([d.allowed_px for d in demands])
    lo = max(float(np.percentile(radius, 0.2)), settings.min_radius_px)
    hi = float(np.percentile(radius, 99.8))
    if hi - lo < settings.min_spacing_px:
        raise PlanError(f"the pilot's surface spans only {max(hi - lo, 0):.1f} px of ring radius: nothing to plan")
    edges = np.arange(lo, hi + settings.bin_px, settings.bin_px)
    which = np.clip(((radius - lo) // settings.bin_px).astype(int), 0, len(edges) - 1)
    order = np.argsort(which, kind="stable")
    bounds = np.searchsorted(which[order], np.arange(len(edges) + 1))
    profile = np.full(len(edges), np.nan)
    for b in range(len(edges)):
        chunk = allowed[order[bounds[b] : bounds[b + 1]]]
        if len(chunk) >= 3:
            profile[b] = np.percentile(chunk, 100.0 * (1.0 - settings.demand_quantile))
    known = np.flatnonzero(np.isfinite(profile))
    if len(known) == 0:
        raise PlanError("no smooth surface in the pilot: every curvature fit straddles an edge")
    profile = np.interp(np.arange(len(edges)), known, profile[known])
    return edges, np.clip(profile, settings.min_spacing_px, settings.max_spacing_px)


def graded(profile: np.ndarray, bin_px: float, slope: float = GRADE) -> np.ndarray:
    """The spacing profile with each bin's spacing at most `slope` px per px of radius above its
    neighbours', either way: a gap grows by half of itself to the next at most (slope 0.5). Beyond
    the surface the pilot saw (a flank it could not read, a limb) the surface goes on as it was,
    not as flat as the bench further out; a plan that jumped from dense to sparse there bridged a
    torus's outer flank with one gap."""
    step = slope * bin_px * np.arange(len(profile))
    ahead = step + np.minimum.accumulate(profile - step)
    behind = (step + np.minimum.accumulate(profile[::-1] - step))[::-1]
    return np.minimum(ahead, behind)


def place_rings(edges: np.ndarray, profile: np.ndarray, bin_px: float, last_px: float = np.inf) -> list[float]:
    """Radii from the first bin outward, each gap the least spacing allowed anywhere inside it, none
    beyond `last_px` (the farthest a ring the projector shows whole can be)."""
    end = min(edges[-1] + bin_px, last_px)
    radii = [float(edges[0])]
    while radii[-1] < end:
        r = radii[-1]
        step = _allowed_at(edges, profile, bin_px, r, r)
        for _ in range(64):  # shrink until every radius in the gap allows it (converges in a few)
            tighter = _allowed_at(edges, profile, bin_px, r, r + step)
            if tighter >= step:
                break
            step = tighter
        if last_px - r < 0.5 * step:
            break  # a ring at the frame's reach would crowd this one: it closes the last annulus
        radii.append(min(r + step, last_px))
    return radii


def _allowed_at(edges: np.ndarray, profile: np.ndarray, bin_px: float, start: float, stop: float) -> float:
    first = int(np.clip((start - edges[0]) // bin_px, 0, len(edges) - 1))
    last = int(np.clip((stop - edges[0]) // bin_px, 0, len(edges) - 1))
    return float(profile[first : last + 1].min())


def uniform_rings(edges: np.ndarray, profile: np.ndarray, bin_px: float) -> tuple[int, float]:
    """The fewest evenly spaced rings under the bound: count and spacing (px)."""
    span = edges[-1] + bin_px - edges[0]
    spacing = float(profile.min())
    count = math.ceil(span / spacing - 1e-9) + 1
    return count, span / (count - 1)


def frequency_criterion(
    views: list[PilotView],
    center_px: tuple[float, float],
    settings: RingPlanSettings,
    edges: np.ndarray,
    rate_px_per_mm: float,
) -> dict[str, float | int]:
    """The curvature-frequency criterion on N dense rings `dense_spacing_px` apart over the pilot."""
    span = float(edges[-1] + settings.bin_px - edges[0])
    dense = max(2, int(span // settings.dense_spacing_px) + 1)
    radii = edges[0] + settings.dense_spacing_px * np.arange(dense)
    spectrum = _PooledSpectrum(settings.curve_step_mm)
    for view in views:
        radius, theta, inside = ring_polar(view.projector, view.points, center_px)
        for r in radii:
            for stretch in _ring_stretches(view.projector, view.points, radius, theta, inside, r, settings):
                _, kappa = curve_curvature(stretch, settings.curve_step_mm, settings.curve_smooth_mm)
                spectrum.add(kappa)
    if spectrum.curves == 0:
        raise PlanError("the pilot's rings break into pieces too short to measure their curvature")
    f_max = spectrum.band_limit(settings.energy_fraction)
    density = rate_px_per_mm / settings.dense_spacing_px  # dense rings per mm across the surface
    fraction = float(min(1.0, 2.0 * f_max / density))
    return {
        "dense_rings": dense,
        "dense_spacing_px": settings.dense_spacing_px,
        "f_max_per_mm": round(f_max, 5),
        "f_s": round(fraction, 4),
        "rings": minimum_rings(dense, fraction),
        "curves": spectrum.curves,
    }


class _PooledSpectrum:
    """The energy spectrum of kappa(s) over many curves, on one frequency grid: each curve adds
    |FFT|^2 scaled so that its bins sum to the integral of kappa^2 ds (Parseval), its mean
    included: a curve of constant curvature adds energy at zero frequency only. Strongly bent
    curves weigh more than flat ones, whose curvature is mostly noise."""

    def __init__(self, step_mm: float, bins: int = 256) -> None:
        self.step_mm = step_mm
        self.edges = np.linspace(0.0, 0.5 / step_mm, bins + 1)
        self.energy = np.zeros(bins)
        self.curves = 0

    def add(self, kappa: np.ndarray) -> None:
        power = np.abs(np.fft.rfft(kappa)) ** 2
        power[1:] *= 2.0  # each positive frequency stands for its negative twin too
        if len(kappa) % 2 == 0:
            power[-1] /= 2.0
        freq = np.fft.rfftfreq(len(kappa), self.step_mm)
        which = np.clip(np.searchsorted(self.edges, freq, side="right") - 1, 0, len(self.energy) - 1)
        self.energy += np.bincount(which, power * self.step_mm / len(kappa), len(self.energy))
        self.curves += 1

    def band_limit(self, energy_fraction: float) -> float:
        """The upper edge of the frequency bin in which `energy_fraction` of the energy is reached."""
        cumulative = np.cumsum(self.energy) / max(self.energy.sum(), 1e-300)
        return float(self.edges[min(int(np.searchsorted(cumulative, energy_fraction)) + 1, len(self.edges) - 1)])


def _ring_stretches(
    projector: CameraModel,
    points: np.ndarray,
    radius: np.ndarray,
    theta: np.ndarray,
    inside: np.ndarray,
    r: float,
    settings: RingPlanSettings,
) -> list[np.ndarray]:
    """The pilot's points within half a pixel of ring radius r, averaged in angle bins about
    `curve_step_mm` long, split where the curve jumps or has a gap: smooth 3D ring curves."""
    band = np.flatnonzero(inside & (np.abs(radius - r) <= 0.5))
    if len(band) < 10:
        return []
    px_per_mm = _tangential_rate(projector, points[band])
    step_rad = settings.curve_step_mm * px_per_mm / max(r, 1.0)
    bins = np.floor((theta[band] + np.pi) / step_rad).astype(np.int64)
    unique, inverse, counts = np.unique(bins, return_inverse=True, return_counts=True)
    curve = np.zeros((len(unique), 3))
    np.add.at(curve, inverse.ravel(), points[band])
    curve /= counts[:, None]
    jump = np.linalg.norm(np.diff(curve, axis=0), axis=1) > 4 * settings.curve_step_mm
    gap = np.diff(unique) > 2
    cuts = np.flatnonzero(jump | gap) + 1
    return [part for part in np.split(curve, cuts) if _length(part) >= settings.min_curve_mm]


def _tangential_rate(projector: CameraModel, points: np.ndarray) -> float:
    """Projector pixels per mm across its rays at the points' median depth (f / z; for an
    orthographic projector K holds pixels per mm)."""
    if projector.projection == "orthographic":
        return float(projector.K[0, 0])
    depth = float(np.median(projector.to_device(points)[:, 2]))
    return float(projector.K[0, 0]) / max(depth, 1e-6)


def _length(curve: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum()) if len(curve) > 1 else 0.0


def pilot_curvature(view: PilotView, settings: RingPlanSettings) -> SurfaceCurvature:
    try:
        radius = settings.curvature_radius_mm
        curvature = principal_curvatures(view.points, view.viewpoint, radius, spacing_mm=radius / 2)
    except ValueError as exc:
        raise PlanError(f"pilot: {exc}") from None
    if curvature.valid.mean() < 0.25:
        raise PlanError(
            f"pilot: too sparse for curvature over {radius:g} mm (most neighbourhoods hold one curve, not a "
            "surface): plan from a dense scan, or raise scan.adaptive.curvature_radius_mm"
        )
    return curvature
