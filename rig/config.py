"""Rig descriptions: YAML loaded into pydantic models, validated before any device opens.

Every model forbids unknown keys and bounds every number; lengths are millimetres (`_mm`),
times microseconds (`_us`) or seconds (`_s`), image sizes pixels.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from drivers.dlp.lcr4500 import MIN_8BIT_PERIOD_US as LCR4500_MIN_8BIT_PERIOD_US
from drivers.dlp.lcr4500 import RESOLUTION as LCR4500_RESOLUTION
from drivers.options import HdmiOptions, LightCrafterOptions, OakOptions, PowerOptions, V4l2Options
from rig.calibrate.boards import BoardConfig
from rig.errors import ConfigError
from rig.patterns import codec_class, codec_names
from rig.patterns.gray import GrayParams
from rig.patterns.phase import PhaseParams
from rig.patterns.radial import RadialParams
from rig.patterns.rings import RingsParams

REPO_CONFIG_DIR = Path(__file__).resolve().parent.parent / "config"
DEFAULT_CONFIG = REPO_CONFIG_DIR / "sim.yaml"

Coord = Annotated[float, Field(ge=-100_000.0, le=100_000.0)]
Vec3 = tuple[Coord, Coord, Coord]
Name = Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]{1,32}$")]
Resolution = tuple[Annotated[int, Field(ge=16, le=16384)], Annotated[int, Field(ge=16, le=16384)]]
Extent = Annotated[float, Field(gt=0.0, le=10_000.0)]
Fraction = Annotated[float, Field(ge=0.0, le=1.0)]
Albedo = Fraction | tuple[Fraction, Fraction, Fraction]  # grey, or linear [red, green, blue]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Intrinsics(Strict):
    """Pixels; for an orthographic device fx, fy are pixels per millimetre."""

    fx: float = Field(gt=0, le=1e6)
    fy: float = Field(gt=0, le=1e6)
    cx: float = Field(ge=-1e5, le=1e5)
    cy: float = Field(ge=-1e5, le=1e5)
    skew: float = Field(0.0, ge=-1e4, le=1e4)


class Pose(Strict):
    """Where the device is and what it looks at, in the world frame (bench plane z = 0, z up)."""

    position_mm: Vec3
    look_at_mm: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)

    @model_validator(mode="after")
    def _well_posed(self) -> Pose:
        view = np.subtract(self.look_at_mm, self.position_mm)
        if np.linalg.norm(view) < 1e-6:
            raise ValueError("look_at_mm must differ from position_mm")
        if np.linalg.norm(np.cross(view / np.linalg.norm(view), self.up)) < 1e-6:
            raise ValueError("up must not be parallel to the viewing direction")
        return self


class Geometry(Strict):
    """Ground-truth (simulation) or calibrated geometry of one device."""

    intrinsics: Intrinsics
    distortion: list[Annotated[float, Field(ge=-10.0, le=10.0)]] = Field(
        default_factory=list, max_length=5, description="k1, k2, p1, p2, k3"
    )
    pose: Pose
    projection: Literal["pinhole", "orthographic"] = "pinhole"


class SimProjectorOptions(Strict):
    gamma: float = Field(2.2, ge=0.2, le=5.0)
    brightness: float = Field(1.0, gt=0.0, le=100.0, description="white irradiance at 600 mm, relative")
    black_level: float = Field(0.004, ge=0.0, le=0.5)
    blur_px: float = Field(0.5, ge=0.0, le=20.0)
    latency_s: float = Field(0.0, ge=0.0, le=2.0, description="the simulated projector's true display latency")


class SimFaults(Strict):
    """Faults to inject, for testing what a rig does when a camera fails (counted in frames)."""

    disconnect_after_frames: int | None = Field(None, ge=0, le=10_000_000)
    stall_after_frames: int | None = Field(None, ge=0, le=10_000_000)
    repeat_frame_at: int | None = Field(None, ge=1, le=10_000_000, description="this capture is a stale repeat")
    early_frame_at: int | None = Field(
        None, ge=1, le=10_000_000, description="this capture was exposed before the last flush (a frame too many held)"
    )


class SimCameraOptions(Strict):
    full_scale_exposure_us: float = Field(12000.0, gt=0.0, le=1e7)
    full_well_e: float = Field(10000.0, ge=10.0, le=1e7)
    read_noise_e: float = Field(20.0, ge=0.0, le=1e4)
    gamma: float = Field(1.0, ge=0.2, le=5.0)
    blur_px: float = Field(0.6, ge=0.0, le=20.0)
    frame_period_s: float = Field(1 / 30, gt=0.0, le=10.0)
    buffered_frames: int = Field(0, ge=0, le=16, description="frames the simulated driver holds (stale on capture)")
    faults: SimFaults = SimFaults()


class ProjectorConfig(Strict):
    name: Name
    driver: Literal["sim", "hdmi", "lightcrafter"] = "sim"
    resolution: Resolution
    geometry: Geometry
    latency_s: Annotated[float, Field(ge=0.0, le=2.0)] | Literal["measured"] = Field(
        0.0,
        description="time from show() to the pattern's light on the scene, waited after every pattern; "
        "'measured': the value `slrig doctor --latency` stored in <data_dir>/latency.json",
    )
    sync: Literal["software", "hardware"] = Field(
        "software",
        description="software: show each pattern, wait latency_s, flush, capture; hardware: the projector "
        "plays the whole sequence and its trigger output starts every camera exposure",
    )
    pattern_period_us: int = Field(33334, ge=1000, le=10_000_000, description="pattern period (hardware sync)")
    sim: SimProjectorOptions = SimProjectorOptions()
    hdmi: HdmiOptions = HdmiOptions()
    lightcrafter: LightCrafterOptions = LightCrafterOptions()
    power: PowerOptions | None = None

    @model_validator(mode="after")
    def _driver_fits(self) -> ProjectorConfig:
        if self.driver == "hdmi" and self.sync == "hardware":
            raise ValueError("sync: an HDMI display cannot play a sequence on its own; use software sync")
        if self.driver == "lightcrafter":
            if tuple(self.resolution) != LCR4500_RESOLUTION:
                raise ValueError(f"resolution: a LightCrafter 4500 is {list(LCR4500_RESOLUTION)}")
            if self.sync == "hardware":
                _check_lightcrafter_timing(self.lightcrafter, self.pattern_period_us)
        return self


def _check_lightcrafter_timing(options: LightCrafterOptions, period_us: int) -> None:
    """8-bit patterns run at up to 120 Hz (LightCrafter 4500 user guide) and a video frame's
    patterns must fit in its period."""
    if period_us < LCR4500_MIN_8BIT_PERIOD_US:
        raise ValueError(f"pattern_period_us: 8-bit patterns need at least {LCR4500_MIN_8BIT_PERIOD_US} us")
    frame_us = 1e6 / options.video_rate_hz
    if options.patterns_per_frame * period_us > frame_us:
        raise ValueError(
            f"pattern_period_us: {options.patterns_per_frame} patterns of {period_us} us do not fit in a "
            f"{options.video_rate_hz:g} Hz video frame ({frame_us:.0f} us); use at most "
            f"{int(frame_us // options.patterns_per_frame)} us or fewer lightcrafter.patterns_per_frame"
        )


class CameraConfig(Strict):
    name: Name
    driver: Literal["sim", "v4l2", "oak"] = "sim"
    resolution: Resolution
    geometry: Geometry
    exposure_us: float = Field(10000.0, ge=1.0, le=1e7)
    gain: float = Field(1.0, ge=0.0, le=64.0)
    bit_depth: Literal[8, 10, 12, 16] = 8
    color: bool = Field(False, description="colour sensor (BGR frames); decoding uses their luminance")
    sim: SimCameraOptions = SimCameraOptions()
    v4l2: V4l2Options | None = None
    oak: OakOptions = OakOptions()

    @model_validator(mode="after")
    def _driver_fits(self) -> CameraConfig:
        if self.driver == "v4l2" and self.v4l2 is None:
            raise ValueError("v4l2: the v4l2 driver needs its section (at least device: /dev/video0)")
        return self


class PlaneScene(Strict):
    kind: Literal["plane"]
    size_mm: float = Field(600.0, gt=0, le=10_000)
    albedo: Albedo = 0.7


class SphereScene(Strict):
    kind: Literal["sphere"]
    radius_mm: float = Field(60.0, gt=0, le=5_000)
    center_mm: Vec3 = (0.0, 0.0, 60.0)
    albedo: Albedo = 0.8


class BoxScene(Strict):
    kind: Literal["box"]
    extents_mm: tuple[Extent, Extent, Extent] = (120.0, 80.0, 60.0)
    rotation_deg: Vec3 = (0.0, 0.0, 25.0)
    albedo: Albedo = 0.8
    plane: bool = Field(True, description="put the box on the bench plane")


class SphereOnPlaneScene(Strict):
    kind: Literal["sphere_on_plane"]
    radius_mm: float = Field(60.0, gt=0, le=5_000)
    position_mm: tuple[Coord, Coord] = (0.0, 0.0)
    plane_size_mm: float = Field(600.0, gt=0, le=10_000)
    sphere_albedo: Albedo = (0.85, 0.75, 0.6)
    plane_albedo: Albedo = 0.6


class TerrainScene(Strict):
    kind: Literal["terrain"]
    size_mm: float = Field(400.0, gt=0, le=10_000)
    amplitude_mm: float = Field(40.0, ge=0, le=5_000)
    seed: int = Field(7, ge=0, le=2**31)
    albedo: Albedo = 0.75


class MeshScene(Strict):
    kind: Literal["mesh"]
    path: Path = Field(description="PLY, OBJ or STL; relative paths are relative to the config file")
    scale: float = Field(1.0, gt=0, le=1e6, description="mesh units to millimetres")
    fit_size_mm: float | None = Field(
        None, gt=0, le=10_000, description="if set, scale so the largest extent is this (overrides scale)"
    )
    position_mm: Vec3 = (0.0, 0.0, 0.0)
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)
    albedo: Albedo = 0.8
    plane: bool = Field(True, description="put the mesh on the bench plane")


SceneConfig = Annotated[
    PlaneScene | SphereScene | BoxScene | SphereOnPlaneScene | TerrainScene | MeshScene,
    Field(discriminator="kind"),
]
SCENE_KINDS = ("plane", "sphere", "box", "sphere_on_plane", "terrain", "mesh")


class SimulationConfig(Strict):
    scene: SceneConfig
    ambient: float = Field(0.02, ge=0.0, le=10.0, description="ambient irradiance, relative to white")
    seed: int = Field(1, ge=0, le=2**31)


class MergeConfig(Strict):
    """How the clouds of several (projector, camera) pairs become one (rigs with more than one pair)."""

    enabled: bool = True
    radius_mm: float | None = Field(
        None,
        gt=0,
        le=50,
        description="a point goes if a better one of another pair is this close; null: twice the sampling distance",
    )
    voxel_mm: float | None = Field(
        None, ge=0, le=50, description="thinning grid; null: the coarsest pair's sampling distance; 0: no thinning"
    )
    overlap_cue: bool = Field(True, description="capture dark, each projector white, all white: finds the overlap")
    cue_ratio: float = Field(0.08, gt=0, lt=1, description="overlap: light beyond the brightest projector's share")
    refine: Literal["none", "icp"] = Field("none", description="icp: realign every pair to the first by ICP")
    icp_max_distance_mm: float = Field(5.0, gt=0, le=100, description="ICP correspondences farther apart are ignored")
    pairs: list[tuple[int, int]] | None = Field(
        None, min_length=1, max_length=256, description="the (projector, camera) pairs to reconstruct; null: all"
    )


class ScanConfig(Strict):
    codec: str = "phase"
    gray: GrayParams = GrayParams()
    phase: PhaseParams = PhaseParams()
    rings: RingsParams = RingsParams()
    radial: RadialParams = RadialParams()
    capture_timeout_s: float = Field(5.0, gt=0.0, le=120.0)
    max_depth_jump_mm: float | None = Field(
        2.0,
        gt=0.0,
        le=1000.0,
        description="dense codecs drop a point unless 3 of its 8 neighbours are within this depth of it "
        "(removes mixed pixels on depth edges and isolated decoding errors); null keeps every point",
    )
    save_frames: bool = Field(False, description="keep raw captures in the scan directory")
    merge: MergeConfig = MergeConfig()

    @field_validator("codec")
    @classmethod
    def _known_codec(cls, v: str) -> str:
        if v not in codec_names():
            raise ValueError(f"unknown codec {v!r}; known codecs: {', '.join(codec_names())}")
        return v


class BoardPose(Strict):
    """Where the operator puts the board: its centre and its rotation (x, y, z Euler angles, degrees;
    all zero is flat, face up, columns along world x)."""

    center_mm: Vec3
    rotation_deg: tuple[
        Annotated[float, Field(ge=-180, le=180)],
        Annotated[float, Field(ge=-180, le=180)],
        Annotated[float, Field(ge=-180, le=180)],
    ] = (0.0, 0.0, 0.0)


class CalibrationConfig(Strict):
    board: BoardConfig = BoardConfig()
    views: int = Field(12, ge=3, le=200, description="board poses a simulated calibration session captures")
    poses: list[BoardPose] | None = Field(
        None,
        min_length=3,
        max_length=200,
        description="board poses for the simulated session instead of its own choice; the first defines "
        "the world frame",
    )
    file: Path | None = Field(
        None,
        description="calibration.json (or its folder) that reconstruction uses instead of the devices' geometry; "
        "relative paths are relative to the config file",
    )


class OutputConfig(Strict):
    data_dir: Path = Path("scans")


class ServiceConfig(Strict):
    """`slrig serve`: the job queue and the HTTP surface (host, port and API key are given when it
    starts, never here: a key does not belong in a config file)."""

    max_queue: int = Field(8, ge=1, le=1000, description="jobs waiting beyond the running one; more get 429")
    max_body_bytes: int = Field(65536, ge=1024, le=10 * 1024 * 1024)
    cors_origins: list[str] = Field(default_factory=list, description="browser origins allowed; none: CORS off")
    allowed_hosts: list[str] = Field(
        default_factory=list, description="Host headers accepted besides localhost and the bound address"
    )
    shutdown_timeout_s: float = Field(
        8.0, ge=1.0, le=10.0, description="to stop the running job on SIGTERM (within systemd's TimeoutStopSec=15)"
    )
    health_stale_s: float = Field(120.0, ge=5.0, le=3600.0, description="a running job silent this long is unhealthy")


class RigConfig(Strict):
    name: Name = "bench"
    projectors: list[ProjectorConfig] = Field(min_length=1, max_length=16)
    cameras: list[CameraConfig] = Field(min_length=1, max_length=16)
    simulation: SimulationConfig | None = None
    scan: ScanConfig = ScanConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    output: OutputConfig = OutputConfig()
    service: ServiceConfig = ServiceConfig()

    @model_validator(mode="after")
    def _consistent(self) -> RigConfig:
        names = [d.name for d in (*self.projectors, *self.cameras)]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(
                f"cameras/projectors[].name: device names must be unique; repeated: {', '.join(duplicates)}"
            )
        model = self.scan.rings.model
        if model != "cone":
            needs = {"parallel": ("orthographic", "orthographic"), "radius_ratio": ("orthographic", "pinhole")}[model]
            if any(p.geometry.projection != needs[0] for p in self.projectors) or any(
                c.geometry.projection != needs[1] for c in self.cameras
            ):
                raise ValueError(
                    f"scan.rings.model: {model!r} needs {needs[0]} projectors and {needs[1]} cameras "
                    "(geometry.projection); the 'cone' model works with any"
                )
        if any(p.sync == "hardware" for p in self.projectors):
            for i, camera in enumerate(self.cameras):
                if camera.driver == "v4l2":
                    raise ValueError(
                        f"cameras[{i}].driver: a V4L2 camera has no trigger input here; use sync: software "
                        "or a camera with one (oak)"
                    )
        drivers = {d.driver == "sim" for d in (*self.projectors, *self.cameras)}
        if len(drivers) > 1:
            raise ValueError(
                "projectors/cameras[].driver: simulated and real devices cannot share a rig "
                "(the simulator lights and sees only its own devices)"
            )
        uses_sim = drivers == {True}
        if uses_sim and self.simulation is None:
            raise ValueError("simulation: simulated devices need a 'simulation' section with a scene")
        for k, (p, c) in enumerate(self.scan.merge.pairs or []):
            if not (0 <= p < len(self.projectors) and 0 <= c < len(self.cameras)):
                raise ValueError(f"scan.merge.pairs[{k}]: ({p}, {c}) names no projector and camera of this rig")
        params = getattr(self.scan, self.scan.codec, None)
        for i, projector in enumerate(self.projectors):
            try:  # codec parameters that only fail against a projector's size (e.g. ring spacing)
                codec_class(self.scan.codec)(projector.resolution, params)
            except ValueError as exc:
                raise ValueError(f"scan.{self.scan.codec} (for projectors[{i}]): {exc}") from None
        return self

    def with_codec(self, codec: str) -> RigConfig:
        """A copy that scans with `codec`, validated like the file."""
        data = self.model_dump()
        data["scan"]["codec"] = codec
        return _validate(data, "--codec")

    def with_scene(self, scene: dict[str, object], source: str = "--scene") -> RigConfig:
        if self.simulation is None:
            raise ConfigError(source, ["simulation: this rig has no simulated scene to replace"])
        data = self.model_dump()
        data["simulation"]["scene"] = scene
        return _validate(data, source)


def _location(loc: tuple[int | str, ...]) -> str:
    out = ""
    for i, item in enumerate(loc):
        if isinstance(item, int):
            out += f"[{item}]"
        elif i > 0 and loc[i - 1] == "scene" and item in SCENE_KINDS:
            continue  # the discriminator's tag adds nothing for the reader
        elif not str(item).isidentifier():
            continue  # a union member's tag, e.g. 'tuple[constrained-float, ...]'
        else:
            out += ("." if out else "") + str(item)
    return out


def _problems(exc: ValidationError) -> list[str]:
    """One line per problem, each starting with the field it is about. Of the errors a union
    field gets (one per member it failed), the most specific is kept."""
    by_field: dict[str, tuple[int, str]] = {}
    for error in exc.errors():
        message = error["msg"].removeprefix("Value error, ")
        where = _location(error["loc"])
        if not where:  # a check across fields: its message names the field
            by_field.setdefault(message, (0, message))
            continue
        loc = error["loc"]
        tags = [i for i, item in enumerate(loc) if isinstance(item, str) and not item.isidentifier()]
        key = _location(loc[: tags[0]]) if tags else where  # the union field, whatever member failed
        if key not in by_field or len(loc) > by_field[key][0]:
            by_field[key] = (len(loc), f"{where}: {message}")
    return [line for _, line in by_field.values()]


def config_from_dict(data: object, source: str) -> RigConfig:
    """Validate a config given as data (a stored scan's snapshot, a request) like a file."""
    config = _validate(data, source)
    _check_files(config, source)
    return config


def _validate(data: object, source: str) -> RigConfig:
    try:
        return RigConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(source, _problems(exc)) from None


def load_config(path: str | Path | None = None) -> RigConfig:
    """Read and validate a rig description; raises ConfigError listing every problem."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    source = str(path)
    if not path.is_file():
        raise ConfigError(source, [f"(file): no such file: {path}"])
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ConfigError(source, [f"(file): not valid YAML: {exc}"]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(source, [f"(file): cannot read: {exc}"]) from None
    if not isinstance(data, dict):
        raise ConfigError(source, ["(top level): expected a mapping of sections"])
    _resolve_paths(data, path.parent)
    config = _validate(data, source)
    _check_files(config, source)
    return config


def _resolve_paths(data: dict, base: Path) -> None:  # type: ignore[type-arg]
    """Paths in the file are relative to the file's folder."""

    def resolve(section: object, key: str) -> None:
        if isinstance(section, dict) and isinstance(section.get(key), str):
            p = Path(section[key]).expanduser()
            section[key] = str(p if p.is_absolute() else (base / p).resolve())

    simulation = data.get("simulation")
    resolve(simulation.get("scene") if isinstance(simulation, dict) else None, "path")
    resolve(data.get("calibration"), "file")


def _check_files(config: RigConfig, source: str) -> None:
    scene = config.simulation.scene if config.simulation else None
    if isinstance(scene, MeshScene) and not scene.path.is_file():
        raise ConfigError(source, [f"simulation.scene.path: mesh file not found: {scene.path}"])
    file = config.calibration.file
    if file is not None and not (
        file.is_file() or (file / "calibration.json").is_file() or (file / "response.json").is_file()
    ):
        raise ConfigError(source, [f"calibration.file: no calibration.json or response.json at {file}"])
