"""Opening a rig: every device of a config built through the driver table, in its world, with the
geometry that reconstruction uses (the config's, or a calibration's) and the projectors' response."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from drivers.base import Camera, Device, Projector
from rig.assembly.memory import check_memory
from rig.assembly.power import ProjectorPower
from rig.assembly.world import World
from rig.calibrate import JSON_NAME, calibration_world, load_calibration, load_response_luts
from rig.config import DeviceKind, DriverEntry, Geometry, RigConfig, driver, named
from rig.errors import ConfigError
from rig.geometry import CameraModel, look_at_rotation
from rig.opened_rig import Rig
from rig.workers import heap_images


def factory_of(entry: DriverEntry) -> Callable[..., Any]:
    """The factory the table names for a driver."""
    return named(entry.factory)  # type: ignore[no-any-return]


def built(entry: DriverEntry, config: Any, index: int, world: World) -> Any:
    """The device the driver's factory builds from its config (the simulated bench's, in its world)."""
    factory = factory_of(entry)
    return factory(config, index, world) if entry.simulated else factory(config)


def geometry_model(geometry: Geometry, resolution: tuple[int, int]) -> CameraModel:
    """The CameraModel described by a config's geometry section."""
    i = geometry.intrinsics
    K = np.array([[i.fx, i.skew, i.cx], [0.0, i.fy, i.cy], [0.0, 0.0, 1.0]])
    position = np.array(geometry.pose.position_mm, dtype=float)
    R = look_at_rotation(position, np.array(geometry.pose.look_at_mm, float), np.array(geometry.pose.up, float))
    return CameraModel(
        width=resolution[0],
        height=resolution[1],
        K=K,
        R=R,
        t=-R @ position,
        dist=np.array(geometry.distortion, dtype=float),
        projection=geometry.projection,
    )


def _calibration_folder(config: RigConfig) -> Path:
    file = config.calibration.file
    if file is None:
        raise ConfigError("calibration.file", ["calibration.file: not set"])
    return file if file.is_dir() else file.parent


def _calibrated_models(
    config: RigConfig, cameras: list[CameraModel], projectors: list[CameraModel]
) -> tuple[list[CameraModel], list[CameraModel], str | None]:
    """Models from calibration.json when the calibration folder has one, else the config's."""
    folder = _calibration_folder(config)
    if not (folder / JSON_NAME).is_file():
        return cameras, projectors, None
    models, digest = load_calibration(folder)
    if config.simulated and calibration_world(folder) != "board":
        raise ConfigError(
            "calibration.file",
            [
                f"calibration.file: {folder} is written in the first camera's frame (--world camera); the simulated "
                "bench's truth is in the board's: calibrate with --world board to scan it"
            ],
        )
    missing = [d.name for d in (*config.cameras, *config.projectors) if d.name not in models]
    if missing:
        raise ConfigError("calibration.file", [f"calibration.file: has no calibration for {', '.join(missing)}"])
    return [models[c.name] for c in config.cameras], [models[p.name] for p in config.projectors], digest


def _response_luts(config: RigConfig) -> tuple[list[np.ndarray | None], str | None]:
    loaded = load_response_luts(_calibration_folder(config))
    if loaded is None:
        return [None] * len(config.projectors), None
    luts, digest = loaded
    return [luts.get(p.name) for p in config.projectors], digest


def world_of(config: RigConfig, cameras: list[CameraModel], projectors: list[CameraModel]) -> World:
    """The real world, or the simulated bench with the devices' true geometry."""
    if not config.simulated:
        return World()
    from rig.assembly import simulated  # the simulator (trimesh, Embree) loads for simulated rigs only

    return simulated.world(config, cameras, projectors)


def build_devices(config: RigConfig, world: World) -> tuple[list[Device], list[Projector], list[Camera]]:
    """Housekeeping devices (power controls), projectors and cameras of `config`, each built by
    its driver's factory in `world`; none is opened yet."""
    extras: list[Device] = [
        ProjectorPower(built(driver(DeviceKind.POWER, p.power.protocol), p, i, world), p.power.input)
        for i, p in enumerate(config.projectors)
        if p.power is not None
    ]
    projectors = [built(driver(DeviceKind.PROJECTOR, p.driver), p, i, world) for i, p in enumerate(config.projectors)]
    cameras = [built(driver(DeviceKind.CAMERA, c.driver), c, i, world) for i, c in enumerate(config.cameras)]
    return extras, projectors, cameras  # type: ignore[return-value]


def rig_geometry(config: RigConfig) -> tuple[list[CameraModel], list[CameraModel]]:
    """The cameras' and projectors' models reconstruction uses (calibrated where the config names a
    calibration), without devices or the simulated world: what reading a stored scan needs."""
    projector_models = [geometry_model(p.geometry, p.resolution) for p in config.projectors]
    camera_models = [geometry_model(c.geometry, c.resolution) for c in config.cameras]
    if config.calibration.file is not None:
        camera_models, projector_models, _ = _calibrated_models(config, camera_models, projector_models)
    return camera_models, projector_models


def open_rig(config: RigConfig, with_devices: bool = True) -> Rig:
    """Open every device of `config` (housekeeping first, then projectors, then cameras; on any
    failure everything opened is closed again). Without devices, a rig of geometry only (and the
    simulated bench's ground truth), for reprocessing stored frames. ConfigError, before anything
    is allocated, for a rig whose scan would need more memory than the machine has available."""
    check_memory(config)
    heap_images(max((c.resolution[0] * c.resolution[1] for c in config.cameras), default=0))
    projector_models = [geometry_model(p.geometry, p.resolution) for p in config.projectors]
    camera_models = [geometry_model(c.geometry, c.resolution) for c in config.cameras]
    world = world_of(config, camera_models, projector_models)  # the true geometry, whatever reconstruction uses
    digest, response_digest = None, None
    luts: list[np.ndarray | None] = [None] * len(config.projectors)
    if config.calibration.file is not None:
        camera_models, projector_models, digest = _calibrated_models(config, camera_models, projector_models)
        luts, response_digest = _response_luts(config)
    rig = Rig(
        config,
        [],
        [],
        projector_models,
        camera_models,
        clock=world.clock,
        truth=world.truth,
        scene=world.scene,
        calibration_sha256=digest,
        response_luts=luts,
        response_sha256=response_digest,
    )
    if with_devices:
        try:
            rig.extras, rig.projectors, rig.cameras = build_devices(config, world)
            for device in (*rig.extras, *rig.projectors, *rig.cameras):
                device.open()
        except BaseException:
            rig.close()
            raise
    return rig
