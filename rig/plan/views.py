"""Viewpoint planning: few projector-camera heads that cover a chosen fraction of an object.

Candidate heads stand on a sphere around the object (a Fibonacci lattice) or where the operator
lists them, each a camera looking at the centre with its projector beside it (`baseline_deg` about
the camera's own vertical image axis, so every head triangulates at that angle). A surface sample
is covered by a head when both see it unoccluded within `max_angle_deg` of its normal (the
dissertation's visibility rule). Set cover is NP-hard: heads are chosen greedily by the area they
add until the target is met, then any head the others make redundant is dropped, then projectors
whose light other heads' projectors already give. `confirm_on_bench` renders the plan on the
simulated bench and measures the coverage from what its cameras see lit, independently of the
planner's ray casts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from drivers.sim import scene as sim_scene
from drivers.sim.bench import SimBench
from drivers.sim.raycast import RayCaster
from rig.geometry import CameraModel, look_at_rotation

CONFIRM_RESOLUTION = (640, 480)


@dataclass(frozen=True)
class ViewPlan:
    cameras: list[np.ndarray]  # positions, mm; every device looks at `center`
    projectors: list[np.ndarray]
    center: np.ndarray
    coverage: float  # of the object's area, by the planner's visibility rule
    samples: int
    candidates: int

    def as_dict(self) -> dict[str, object]:
        def pose(p: np.ndarray) -> dict[str, list[float]]:
            return {
                "position_mm": [round(float(x), 2) for x in p],
                "look_at_mm": [round(float(x), 2) for x in self.center],
            }

        return {
            "cameras": [pose(p) for p in self.cameras],
            "projectors": [pose(p) for p in self.projectors],
            "coverage": round(self.coverage, 4),
            "surface_samples": self.samples,
            "candidates": self.candidates,
        }


def surface_samples(scene: sim_scene.Scene, spacing_mm: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Points spread over the surface by area (about one per spacing^2) with their face normals."""
    tri = scene.vertices[scene.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normals = cross / np.maximum(2 * area, 1e-12)[:, None]
    count = max(1000, int(area.sum() / spacing_mm**2))
    rng = np.random.default_rng(seed)
    face = rng.choice(len(area), count, p=area / area.sum())
    a, b = rng.random((2, count))
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    t = tri[face]
    points = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
    return points, normals[face]


def sphere_positions(center: np.ndarray, distance: float, count: int, min_elevation_deg: float) -> np.ndarray:
    """`count` directions of a Fibonacci lattice above `min_elevation_deg`, at `distance`."""
    k = np.arange(count) + 0.5
    lowest = np.sin(np.radians(min_elevation_deg))
    z = lowest + (1 - lowest) * k / count  # uniform in z: uniform in area on the sphere's band
    azimuth = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z**2)
    return center + distance * np.stack([r * np.cos(azimuth), r * np.sin(azimuth), z], axis=1)


def _look_up(position: np.ndarray, center: np.ndarray) -> np.ndarray:
    """The up vector a device at `position` uses: world z, or world y looking straight up or down."""
    direction = (center - position) / np.linalg.norm(center - position)
    return np.array([0.0, 0.0, 1.0]) if abs(direction[2]) < 0.99 else np.array([0.0, 1.0, 0.0])


def beside(cameras: np.ndarray, center: np.ndarray, degrees: float) -> np.ndarray:
    """Projector positions: each camera's position turned about its own vertical image axis
    through the centre, so the head's baseline runs across the camera's image rows."""
    out = []
    for position in cameras:
        axis = look_at_rotation(position, center, _look_up(position, center))[1]  # image y, in the world
        out.append(center + Rotation.from_rotvec(np.radians(degrees) * axis).apply(position - center))
    return np.array(out)


def visible(
    caster: RayCaster, points: np.ndarray, normals: np.ndarray, position: np.ndarray, max_angle_deg: float
) -> np.ndarray:
    """Which samples a device at `position` sees: facing it within the angle, nothing in between.
    (Normals of a closed mesh point outward; either side counts for an open one.)"""
    to_device = position - points
    distance = np.linalg.norm(to_device, axis=1)
    direction = to_device / distance[:, None]
    facing = np.abs(np.einsum("ij,ij->i", direction, normals)) >= np.cos(np.radians(max_angle_deg))
    out = np.zeros(len(points), bool)
    idx = np.flatnonzero(facing)
    if len(idx):
        hit, _ = caster.first_hit(np.broadcast_to(position, (len(idx), 3)).copy(), -direction[idx])
        out[idx] = hit >= distance[idx] - max(0.5, 1e-4 * float(distance.max()))
    return out


def plan_views(
    scene: sim_scene.Scene,
    coverage: float = 0.95,
    candidates: int = 120,
    distance_mm: float | None = None,
    max_angle_deg: float = 65.0,
    baseline_deg: float = 15.0,
    min_elevation_deg: float = -90.0,
    spacing_mm: float = 2.0,
    positions: np.ndarray | None = None,
) -> ViewPlan:
    """`positions`: the operator's candidate camera positions (N, 3), instead of the sphere."""
    points, normals = surface_samples(scene, spacing_mm)
    center = 0.5 * (scene.vertices.min(axis=0) + scene.vertices.max(axis=0))
    radius = float(np.linalg.norm(scene.vertices - center, axis=1).max())
    distance = distance_mm or 4.0 * radius
    if positions is None:
        cams = sphere_positions(center, distance, candidates, min_elevation_deg)
    else:
        cams = np.asarray(positions, float).reshape(-1, 3)
    projs = beside(cams, center, baseline_deg)
    caster = RayCaster(scene.vertices, scene.faces)
    seen = np.stack([visible(caster, points, normals, p, max_angle_deg) for p in cams])
    lit = np.stack([visible(caster, points, normals, p, max_angle_deg) for p in projs])
    heads = seen & lit
    chosen: list[int] = []
    covered = np.zeros(len(points), bool)
    while covered.mean() < coverage:
        gain = (heads & ~covered).sum(axis=1)
        best = int(np.argmax(gain))
        if gain[best] == 0:
            break  # nothing more can be covered from these candidates
        chosen.append(best)
        covered |= heads[best]
    goal = min(coverage, covered.mean())
    for head in sorted(chosen, key=lambda h: int(heads[h].sum())):  # greedy picks early ones others replace
        rest = [h for h in chosen if h != head]
        if rest and heads[rest].any(axis=0).mean() >= goal:
            chosen = rest
    cameras, projectors = list(chosen), list(chosen)
    for head in sorted(chosen, key=lambda h: int(lit[h].sum())):  # drop projectors others replace
        rest = [p for p in projectors if p != head]
        if rest and (seen[cameras].any(axis=0) & lit[rest].any(axis=0)).mean() >= goal:
            projectors = rest
    final = (seen[cameras].any(axis=0) & lit[projectors].any(axis=0)).mean() if cameras else 0.0
    return ViewPlan(
        cameras=[cams[i] for i in cameras],
        projectors=[projs[i] for i in projectors],
        center=center,
        coverage=float(final),
        samples=len(points),
        candidates=len(cams),
    )


def _device(position: np.ndarray, center: np.ndarray, radius: float) -> CameraModel:
    width, height = CONFIRM_RESOLUTION
    distance = float(np.linalg.norm(position - center))
    half_angle = np.arcsin(min(0.99, 1.1 * radius / distance))
    f = 0.5 * min(width, height) / np.tan(half_angle)
    rotation = look_at_rotation(position, center, _look_up(position, center))
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
    return CameraModel(width, height, K, rotation, -rotation @ position)


def confirm_on_bench(scene: sim_scene.Scene, plan: ViewPlan, spacing_mm: float = 2.0) -> float:
    """Coverage of the plan as the simulated bench renders it: the fraction of surface samples
    with a point that some camera sees lit by some projector within one sample spacing."""
    radius = float(np.linalg.norm(scene.vertices - plan.center, axis=1).max())
    cameras = [_device(p, plan.center, radius) for p in plan.cameras]
    projectors = [_device(p, plan.center, radius) for p in plan.projectors]
    bench = SimBench(scene, cameras, projectors)
    found = []
    for c in range(len(cameras)):
        lit = np.zeros((cameras[c].height, cameras[c].width), bool)
        truth = None
        for p in range(len(projectors)):
            truth = bench.ground_truth(c, p)
            lit |= truth.hit & truth.lit
        assert truth is not None
        found.append(truth.points[lit])
    if not found or not sum(len(f) for f in found):
        return 0.0
    samples, _ = surface_samples(scene, spacing_mm, seed=1)
    distance, _ = cKDTree(np.concatenate(found)).query(samples, distance_upper_bound=spacing_mm)
    return float(np.isfinite(distance).mean())
