"""The dissertation's descriptor (ch.8; reference 5.6): K rings about a reference point on the
surface, M samples on each at fixed polar angles, each sample's geodesic distance to the reference
point, and the magnitude of the Fourier transform, compared by correlation.

The rings are circles of radius R_k about an axis through the reference point, met on the surface.
`frame: viewer` (the published choice) takes the viewing axis and the apex along it; `frame:
balanced` (default) starts there and tilts the axis until the surface's heights on the rings have
no first harmonic, then finds the apex again along it (`balanced_frame`), so that a small tilt of
the object moves neither. The magnitude of each ring's spectrum does not change when the object
turns about the axis (the samples shift along the ring), nor when it moves.

- `spectrum: per_ring` (default): each ring's distances less the ring's radius (what the surface
  adds to a flat disc), |FFT| per ring, concatenated: exactly invariant to turns by a multiple of
  2 pi / M, and the rings' common radius no longer dominates the correlation;
- `spectrum: concatenated`: the published variant, |FFT| of all rings' distances in one signal.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from rig.errors import RecognitionError
from rig.recognition.geodesic import HeightField, fill_holes, geodesic_distances, height_field, sample

MAX_MISSING = 0.05  # the fraction of ring samples that may fall in holes (filled along the ring)
_APEX_SUPPORT = 8  # the apex is the nearest point to the viewer with this many points within ...
_APEX_RADIUS_MM = 1.5  # ... this distance: a lone outlier is not an apex
FRAME_ITERATIONS = 12  # steps toward the balanced frame's axis at most (3 to 6 on faces)
_FRAME_SETTLED_DEG = 0.05  # the rings' slope at which the frame is balanced
_FRAME_MAX_STEP_DEG = 5.0  # the largest tilt of one step
FRAME_CELL_MM = 2.0  # the balanced frame's rings are sampled on a coarser field
_APEX_REACH_MM = 15.0  # a re-centred apex stays on the feature it started on


@dataclass(frozen=True)
class DescriptorSettings:
    rings: int = 8
    samples: int = 64
    inner_mm: float = 6.0
    outer_mm: float = 48.0
    distance: Literal["geodesic", "euclidean"] = "geodesic"
    spectrum: Literal["per_ring", "concatenated"] = "per_ring"
    frame: Literal["balanced", "viewer"] = "balanced"
    cell_mm: float = 1.0

    def __post_init__(self) -> None:
        """ValueError naming the first setting out of its range."""
        checks = [
            ("rings", 1 <= self.rings <= 64, "1 to 64"),
            ("samples", 8 <= self.samples <= 1024 and self.samples % 2 == 0, "an even number, 8 to 1024"),
            ("inner_mm", 0 < self.inner_mm < self.outer_mm, "above 0 and below outer_mm"),
            ("outer_mm", self.outer_mm <= 500, "at most 500"),
            ("distance", self.distance in ("geodesic", "euclidean"), "geodesic or euclidean"),
            ("spectrum", self.spectrum in ("per_ring", "concatenated"), "per_ring or concatenated"),
            ("frame", self.frame in ("balanced", "viewer"), "balanced or viewer"),
            ("cell_mm", 0.1 <= self.cell_mm <= 10 and self.cell_mm < self.inner_mm, "0.1 to 10 and below inner_mm"),
        ]
        for name, ok, expected in checks:
            if not ok:
                raise ValueError(f"{name}: {getattr(self, name)!r} is not {expected}")

    def radii(self) -> np.ndarray:
        return np.linspace(self.inner_mm, self.outer_mm, self.rings)

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class Descriptor:
    features: np.ndarray  # (K * (M // 2 + 1),) or (K * M // 2 + 1,) float64
    distances: np.ndarray  # (K, M) each ring sample's distance to the reference point, mm
    reference: np.ndarray  # (3,)
    axis: np.ndarray  # (3,) unit, toward the viewer: the rings are circles about it
    settings: DescriptorSettings


def apex(points: np.ndarray, toward_viewer: np.ndarray) -> np.ndarray:
    """The point of the surface nearest the viewer along `toward_viewer`, ignoring lone points (a
    point needs `_APEX_SUPPORT` others within `_APEX_RADIUS_MM`, or 3 point spacings in a sparse scan)."""
    height = points @ (toward_viewer / np.linalg.norm(toward_viewer))
    top = np.argpartition(-height, 2000)[:2000] if len(height) > 2000 else np.arange(len(height))
    order = top[np.argsort(-height[top])]
    if len(order) < 2:
        raise RecognitionError("no apex: the scan has fewer than two points")
    spacing = float(np.median(cKDTree(points[order]).query(points[order], k=2)[0][:, 1]))
    radius = max(_APEX_RADIUS_MM, 3.0 * spacing)
    tree = cKDTree(points[height >= height[order[-1]] - radius])  # every candidate's neighbours
    support = np.array([len(n) for n in tree.query_ball_point(points[order], radius)])
    found = np.flatnonzero(support > _APEX_SUPPORT)
    if len(found) == 0:
        raise RecognitionError("no apex: the scan has no surface of more than a few scattered points")
    return points[order[found[0]]]


def describe(
    points: np.ndarray,
    toward_viewer: np.ndarray,
    settings: DescriptorSettings | None = None,
    reference: np.ndarray | None = None,
) -> Descriptor:
    """The descriptor of the surface sampled by `points` (N, 3), seen along `toward_viewer` (the
    direction from the surface to the projector), about `reference` (default: the apex)."""
    settings = settings or DescriptorSettings()
    if len(points) == 0:
        raise RecognitionError("the scan has no points")
    axis = np.asarray(toward_viewer, float) / np.linalg.norm(toward_viewer)
    if reference is None:
        reference = apex(points, axis)
        if settings.frame == "balanced":
            reference, axis = balanced_frame(points, reference, axis, settings)
    reference = np.asarray(reference, float)
    field = fill_holes(height_field(points, reference, axis, 1.5 * settings.outer_mm, settings.cell_mm))
    on_surface = ring_points(field, reference, settings)
    if settings.distance == "geodesic":
        distances = sample(field, geodesic_distances(field, reference), on_surface.reshape(-1, 3))
    else:
        distances = np.linalg.norm(on_surface.reshape(-1, 3) - reference, axis=1)
    distances = _fill_along_rings(distances.reshape(settings.rings, settings.samples), settings)
    return Descriptor(spectrum(distances, settings), distances, reference, axis, settings)


def balanced_frame(
    points: np.ndarray, reference: np.ndarray, axis: np.ndarray, settings: DescriptorSettings
) -> tuple[np.ndarray, np.ndarray]:
    """The reference point and axis a small tilt of the object does not change: the axis about
    which the surface's heights on the rings have no first harmonic (a tilt adds r tan(t) cos(a)
    to them: a plane fitted to the ring samples), with the apex along it near where it was.

    The balancing tilt is the root of the rings' slope as a function of the tilt. Tilting by the
    slope itself (the fixed-point step) assumes the slope falls one for one with the tilt, but the
    apex follows the axis: on faces it slides along the nose, and that step swung between two axes
    ever further apart (10 degrees after six steps). Broyden's method learns the response from the
    steps taken; a step is at most `_FRAME_MAX_STEP_DEG`, and the most balanced frame seen is kept."""
    start = np.asarray(axis, float) / np.linalg.norm(axis)
    across = np.linalg.svd(start[None, :])[2][1:]  # (2, 3): an orthonormal basis across the start axis
    tilt, response = np.zeros(2), np.eye(2)
    best = (np.inf, reference, start)
    previous: tuple[np.ndarray, np.ndarray] | None = None
    settled, limit = np.tan(np.radians(_FRAME_SETTLED_DEG)), np.tan(np.radians(_FRAME_MAX_STEP_DEG))
    for step in range(FRAME_ITERATIONS):
        axis = start + tilt @ across
        axis /= np.linalg.norm(axis)
        if step > 0:  # the apex along the new axis, on the feature it started on
            near = np.linalg.norm(np.cross(points - reference, axis), axis=1) <= _APEX_REACH_MM
            reference = apex(points[near], axis)
        slope = across @ ring_slope(points, reference, axis, settings)
        size = float(np.linalg.norm(slope))
        if size < best[0]:
            best = (size, reference, axis)
        if size < settled:
            break
        if previous is not None:  # Broyden's update: the response that explains the last step
            moved, changed = tilt - previous[0], slope - previous[1]
            response += np.outer(changed - response @ moved, moved) / max(float(moved @ moved), 1e-18)
        try:
            change = -np.linalg.solve(response, slope)
        except np.linalg.LinAlgError:
            change = -slope
        change *= min(1.0, limit / max(float(np.linalg.norm(change)), 1e-18))
        previous = (tilt, slope)
        tilt = tilt + change
    return best[1], best[2]


def ring_slope(points: np.ndarray, reference: np.ndarray, axis: np.ndarray, settings: DescriptorSettings) -> np.ndarray:
    """(3,) the slope of the plane fitted to the surface's heights along `axis` on the rings about
    `reference`, as a vector across the axis: the tilt the rings see."""
    field = height_field(points, reference, axis, settings.outer_mm + FRAME_CELL_MM, FRAME_CELL_MM)
    on_rings = ring_points(field, reference, settings).reshape(-1, 3)
    on_rings = on_rings[np.isfinite(on_rings[:, 0])]
    if len(on_rings) < 3 * settings.rings:
        raise RecognitionError(
            f"too little surface around the reference point: {len(on_rings)} ring samples "
            f"within {settings.outer_mm:g} mm"
        )
    local = (on_rings - reference) @ field.axes.T
    design = np.column_stack([np.ones(len(local)), local[:, :2]])
    _, slope_u, slope_v = np.linalg.lstsq(design, local[:, 2], rcond=None)[0]
    return slope_u * field.axes[0] + slope_v * field.axes[1]


def ring_points(field: HeightField, reference: np.ndarray, settings: DescriptorSettings) -> np.ndarray:
    """(K, M, 3) where each ring's circle about the axis through `reference` meets the surface, at
    polar angles 2 pi m / M from the field's u axis (NaN where the surface has a hole)."""
    angle = 2 * np.pi * np.arange(settings.samples) / settings.samples
    radius = settings.radii()[:, None]
    across = (radius * np.cos(angle))[..., None] * field.axes[0] + (radius * np.sin(angle))[..., None] * field.axes[1]
    on_plane = (reference + across).reshape(-1, 3)
    height = sample(field, field.height, on_plane)
    base = (on_plane - field.origin) @ field.axes[2]
    return (on_plane + (height - base)[:, None] * field.axes[2]).reshape(settings.rings, settings.samples, 3)


def spectrum(distances: np.ndarray, settings: DescriptorSettings) -> np.ndarray:
    """The descriptor's features from the ring samples' distances (K, M)."""
    if settings.spectrum == "concatenated":
        signal = distances.ravel()
        return np.abs(np.fft.rfft(signal))[: len(signal) // 2 + 1]
    excess = distances - settings.radii()[:, None]
    return np.abs(np.fft.rfft(excess, axis=1)).ravel()


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two feature vectors of one length."""
    a, b = a - a.mean(), b - b.mean()
    return float(a @ b / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-300))


def _fill_along_rings(distances: np.ndarray, settings: DescriptorSettings) -> np.ndarray:
    """Distances with the few samples in holes interpolated along their ring (circularly)."""
    missing = ~np.isfinite(distances)
    if missing.mean() > MAX_MISSING:
        raise RecognitionError(
            f"too little surface around the reference point: {missing.sum()} of {missing.size} ring samples "
            f"(radii {settings.inner_mm:g} to {settings.outer_mm:g} mm) fall in holes or off the scan "
            f"(at most {MAX_MISSING:.0%})"
        )
    filled = distances.copy()
    m = settings.samples
    for k in np.flatnonzero(missing.any(axis=1)):
        known = np.flatnonzero(~missing[k])
        if len(known) < 2:
            raise RecognitionError(f"ring {k} ({settings.radii()[k]:g} mm) has almost no surface")
        at = np.concatenate([known - m, known, known + m])
        filled[k, missing[k]] = np.interp(np.flatnonzero(missing[k]), at, np.tile(distances[k, known], 3))
    return filled
