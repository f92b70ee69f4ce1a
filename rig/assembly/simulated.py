"""The simulated rig: the bench built from a config's own sections, its devices, and the
capabilities only a simulated rig has (ground truth, a hand on the scene, bench time).

This is the one runtime module that imports the simulator (trimesh, Embree); the assembly loads
it only for a config whose drivers are simulated.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from drivers.base import Camera, Projector
from drivers.sim import scene as sim_scene
from drivers.sim.bench import SimBench
from drivers.sim.camera import SimCamera
from drivers.sim.projector import SimProjector
from drivers.sim.texture import Checker, Decal, Gradient, SolidTexture, Stripes, read_decal_image
from rig.assembly.world import World
from rig.config import (
    BlocksScene,
    BoxScene,
    CameraConfig,
    CheckerTexture,
    GradientTexture,
    MeshScene,
    PlaneScene,
    ProjectorConfig,
    RigConfig,
    SimulationConfig,
    SphereOnPlaneScene,
    SphereScene,
    StepsScene,
    StripesTexture,
    TerrainScene,
    TextureConfig,
)
from rig.errors import SceneError
from rig.geometry import CameraModel


def build_scene(config: SimulationConfig) -> sim_scene.Scene:
    """The simulated scene of a config; raises SceneError for a missing or unreadable mesh."""
    s = config.scene
    objects: list[sim_scene.SceneObject]
    if isinstance(s, PlaneScene):
        objects = [sim_scene.plane(s.size_mm, s.albedo)]
    elif isinstance(s, SphereScene):
        objects = [sim_scene.sphere(s.radius_mm, s.center_mm, s.albedo)]
    elif isinstance(s, SphereOnPlaneScene):
        center = (*s.position_mm, s.radius_mm)
        objects = [
            sim_scene.plane(s.plane_size_mm, s.plane_albedo),
            sim_scene.sphere(s.radius_mm, center, s.sphere_albedo),
        ]
    elif isinstance(s, BoxScene):
        box = sim_scene.box(s.extents_mm, (0.0, 0.0, s.extents_mm[2] / 2), s.rotation_deg, s.albedo)
        objects = [sim_scene.plane(600.0, 0.6), box] if s.plane else [box]
    elif isinstance(s, StepsScene):
        stairs = sim_scene.steps(s.rises_mm, s.run_mm, s.width_mm, s.rotation_deg, s.albedo)
        objects = [sim_scene.plane(600.0, 0.6), stairs] if s.plane else [stairs]
    elif isinstance(s, BlocksScene):
        grid = sim_scene.blocks(s.count, s.block_mm, s.heights_mm, s.seed, s.rotation_deg, s.albedo)
        objects = [sim_scene.plane(600.0, 0.6), grid] if s.plane else [grid]
    elif isinstance(s, TerrainScene):
        objects = [sim_scene.terrain(s.size_mm, s.amplitude_mm, seed=s.seed, albedo=s.albedo)]
    elif isinstance(s, MeshScene):
        try:
            mesh = sim_scene.mesh_file(
                s.path, s.scale, s.position_mm, s.rotation_deg, s.albedo, fit_size_mm=s.fit_size_mm
            )
        except (FileNotFoundError, ValueError) as exc:
            raise SceneError(f"simulation.scene.path: {exc}") from None
        objects = [sim_scene.plane(600.0, 0.6), mesh] if s.plane else [mesh]
    else:  # pragma: no cover - the config union is exhaustive
        raise SceneError(f"unsupported scene kind {s.kind!r}")
    material = config.material
    if material.specular > 0:
        objects = [
            dataclasses.replace(o, specular=material.specular, roughness=material.roughness)
            if o.name != "plane" or material.bench
            else o
            for o in objects
        ]
    return sim_scene.build_scene(objects, build_texture(config.texture))


def build_texture(config: TextureConfig | None) -> SolidTexture | None:
    """The solid texture of a config; raises SceneError for an unreadable image."""
    if config is None:
        return None
    if isinstance(config, StripesTexture):
        return Stripes(config.period_mm, config.direction_mm, config.colours)
    if isinstance(config, CheckerTexture):
        return Checker(config.size_mm, config.colours)
    if isinstance(config, GradientTexture):
        return Gradient(config.period_mm)
    try:
        image = read_decal_image(str(config.path))
    except ValueError as exc:
        raise SceneError(f"simulation.texture.path: {exc}") from None
    return Decal(image, config.size_mm, config.center_mm)


class BenchClock:
    """Bench time: frames are stamped on it and waiting advances it, so a scan takes no real time."""

    def __init__(self, bench: SimBench) -> None:
        self.bench = bench

    def now(self) -> float:
        return self.bench.clock_s

    def sleep(self, seconds: float) -> None:
        self.bench.advance(seconds)


class BoardOnBench:
    """Puts a printed board on the simulated bench, in place of the config's scene."""

    def __init__(self, bench: SimBench) -> None:
        self.bench = bench

    def show_board(self, image: np.ndarray, pixel_mm: float, axes: np.ndarray, origin: np.ndarray) -> None:
        self.bench.set_scene(sim_scene.build_scene([sim_scene.printed_plane("board", image, pixel_mm, axes, origin)]))


@dataclass
class SimulatedWorld(World):
    """The simulated bench: its clock, its ground truth (the bench itself), and its scene."""

    bench: SimBench | None = None


def world(config: RigConfig, cameras: list[CameraModel], projectors: list[CameraModel]) -> SimulatedWorld:
    """The bench of a simulated config, with the devices' true geometry (whatever calibration
    reconstruction uses)."""
    assert config.simulation is not None  # validated: simulated devices need a scene
    bench = SimBench(
        build_scene(config.simulation),
        cameras,
        projectors,
        camera_settings=list(config.cameras),
        camera_options=[c.sim for c in config.cameras],
        projector_options=[p.sim for p in config.projectors],
        ambient=config.simulation.ambient,
        seed=config.simulation.seed,
    )
    return SimulatedWorld(clock=BenchClock(bench), truth=bench, scene=BoardOnBench(bench), bench=bench)


def _bench(world: World) -> SimBench:
    if not isinstance(world, SimulatedWorld) or world.bench is None:
        raise TypeError("simulated devices live on the simulated bench; this world has none")
    return world.bench


def projector(config: ProjectorConfig, index: int, world: World) -> Projector:
    return SimProjector(config.name, _bench(world), index, sequence=config.sync == "hardware")


def camera(config: CameraConfig, index: int, world: World) -> Camera:
    return SimCamera(config.name, _bench(world), index, config.sim.faults)
