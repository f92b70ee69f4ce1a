"""A Rig: the opened devices of a RigConfig with their geometry."""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drivers.base import Camera, Device, Projector
from drivers.sim import SimBench, SimCamera, SimCameraFaults, SimCameraParams, SimProjector, SimProjectorParams
from drivers.sim import scene as sim_scene
from rig.config import (
    BoxScene,
    CameraConfig,
    Geometry,
    MeshScene,
    PlaneScene,
    ProjectorConfig,
    RigConfig,
    SimulationConfig,
    SphereOnPlaneScene,
    SphereScene,
    TerrainScene,
)
from rig.errors import ConfigError, SceneError
from rig.geometry import CameraModel, look_at_rotation
from rig.pipeline.dense import PairTriangulator


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
    return sim_scene.build_scene(objects)


@dataclass(eq=False)
class Rig:
    """Opened devices and their geometry; close() darkens projectors and closes everything."""

    config: RigConfig
    projectors: list[Projector]
    cameras: list[Camera]
    projector_models: list[CameraModel]
    camera_models: list[CameraModel]
    sim: SimBench | None = None
    calibration_sha256: str | None = None  # of calibration.file when reconstruction uses one
    response_luts: list[np.ndarray | None] = field(default_factory=list)  # per projector, from response.json
    response_sha256: str | None = None
    extras: list[Device] = field(default_factory=list)  # housekeeping (projector power), opened first
    # Called at every wait for light: the daemon's heartbeat and cancel check in long sessions.
    checkpoint: Callable[[], None] | None = field(default=None, repr=False)
    _closed: bool = field(default=False, repr=False)
    _triangulators: dict[tuple[int, int], PairTriangulator] = field(default_factory=dict, repr=False)

    def triangulator(self, projector: int, camera: int) -> PairTriangulator:
        """The pair's triangulator; its per-pixel terms are computed on first use and kept."""
        key = (projector, camera)
        if key not in self._triangulators:
            self._triangulators[key] = PairTriangulator(self.camera_models[camera], self.projector_models[projector])
        return self._triangulators[key]

    def latency_s(self, projector: int) -> float:
        """The display latency to wait after showing a pattern on `projector`."""
        value = self.config.projectors[projector].latency_s
        if value != "measured":
            return float(value)
        path = self.config.output.data_dir / "latency.json"
        try:
            return float(json.loads(path.read_text())[self.config.projectors[projector].name])
        except (OSError, ValueError, KeyError) as exc:
            raise ConfigError(
                "config",
                [
                    f"projectors[{projector}].latency_s: 'measured', but {path} has no "
                    f"measurement ({exc}); run `slrig doctor --latency`"
                ],
            ) from None

    def wait(self, seconds: float) -> None:
        """Let time pass: bench time on the simulated bench, real time on real devices."""
        if self.checkpoint is not None:
            self.checkpoint()
        if self.sim is not None:
            self.sim.advance(seconds)
        elif seconds > 0:
            time.sleep(seconds)

    def all_dark(self) -> None:
        for projector in self.projectors:
            with contextlib.suppress(Exception):  # darkening the others matters more than this error
                projector.dark()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.all_dark()
        for device in (*self.projectors, *self.cameras, *self.extras):
            with contextlib.suppress(Exception):  # close every device even if one fails
                device.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _sim_projector_params(p: ProjectorConfig) -> SimProjectorParams:
    return SimProjectorParams(
        gamma=p.sim.gamma,
        brightness=p.sim.brightness,
        black_level=p.sim.black_level,
        blur_px=p.sim.blur_px,
        latency_s=p.sim.latency_s,
    )


def _sim_camera_params(c: CameraConfig) -> SimCameraParams:
    return SimCameraParams(
        exposure_us=c.exposure_us,
        gain=c.gain,
        full_scale_exposure_us=c.sim.full_scale_exposure_us,
        full_well_e=c.sim.full_well_e,
        read_noise_e=c.sim.read_noise_e,
        gamma=c.sim.gamma,
        blur_px=c.sim.blur_px,
        bit_depth=c.bit_depth,
        frame_period_s=c.sim.frame_period_s,
        buffered_frames=c.sim.buffered_frames,
        color=c.color,
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
    from rig.calibrate.files import JSON_NAME, load_calibration  # calibration imports the rig: import late

    folder = _calibration_folder(config)
    if not (folder / JSON_NAME).is_file():
        return cameras, projectors, None
    models, digest = load_calibration(folder)
    missing = [d.name for d in (*config.cameras, *config.projectors) if d.name not in models]
    if missing:
        raise ConfigError("calibration.file", [f"calibration.file: has no calibration for {', '.join(missing)}"])
    return [models[c.name] for c in config.cameras], [models[p.name] for p in config.projectors], digest


def _response_luts(config: RigConfig) -> tuple[list[np.ndarray | None], str | None]:
    from rig.calibrate.response import load_response_luts  # calibration imports the rig: import late

    loaded = load_response_luts(_calibration_folder(config))
    if loaded is None:
        return [None] * len(config.projectors), None
    luts, digest = loaded
    return [luts.get(p.name) for p in config.projectors], digest


def _open_all(rig: Rig, devices: tuple[Device, ...]) -> None:
    try:
        for device in devices:
            device.open()
    except Exception:
        rig.close()
        raise


def _faults(c: CameraConfig) -> SimCameraFaults:
    f = c.sim.faults
    return SimCameraFaults(f.disconnect_after_frames, f.stall_after_frames, f.repeat_frame_at, f.early_frame_at)


def open_rig(config: RigConfig, with_devices: bool = True) -> Rig:
    """Open every device of `config`: the simulated bench, or the real devices. Without devices,
    a rig of geometry only (and the simulated bench's ground truth), for reprocessing stored frames."""
    projector_models = [geometry_model(p.geometry, p.resolution) for p in config.projectors]
    camera_models = [geometry_model(c.geometry, c.resolution) for c in config.cameras]
    truth = (camera_models, projector_models)  # the simulator's geometry, whatever reconstruction uses
    digest = None
    luts: list[np.ndarray | None] = [None] * len(config.projectors)
    response_digest = None
    if config.calibration.file is not None:
        camera_models, projector_models, digest = _calibrated_models(config, camera_models, projector_models)
        luts, response_digest = _response_luts(config)
    bench: SimBench | None = None
    extras: list[Device] = []
    projectors: list[Projector] = []
    cameras: list[Camera] = []
    if config.simulation is None:  # a real rig
        if not with_devices:
            return Rig(config, [], [], projector_models, camera_models, None, digest, luts, response_digest)
        from rig.assembly import hardware  # drivers of real devices, only when a rig has them

        extras, projectors, cameras = hardware.devices(config)
    else:
        bench = SimBench(
            build_scene(config.simulation),
            truth[0],
            truth[1],
            camera_params=[_sim_camera_params(c) for c in config.cameras],
            projector_params=[_sim_projector_params(p) for p in config.projectors],
            ambient=config.simulation.ambient,
            seed=config.simulation.seed,
        )
        if with_devices:
            projectors = [
                SimProjector(p.name, bench, i, sequence=p.sync == "hardware") for i, p in enumerate(config.projectors)
            ]
            cameras = [SimCamera(c.name, bench, i, _faults(c)) for i, c in enumerate(config.cameras)]
    rig = Rig(
        config,
        projectors,
        cameras,
        projector_models,
        camera_models,
        sim=bench,
        calibration_sha256=digest,
        response_luts=luts,
        response_sha256=response_digest,
        extras=extras,
    )
    _open_all(rig, (*extras, *projectors, *cameras))
    return rig
