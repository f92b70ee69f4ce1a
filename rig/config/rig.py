"""The whole rig description: its devices, the simulated scene, and how it scans, calibrates,
stores and serves."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from rig.config.calibration import CalibrationConfig
from rig.config.common import Name, Strict
from rig.config.drivers import DeviceKind, driver, drivers_of
from rig.config.equipment import CameraConfig, ProjectorConfig
from rig.config.problems import validation_problems
from rig.config.scan import ScanConfig
from rig.config.scenes import SimulationConfig
from rig.errors import ConfigError
from rig.patterns import codec_class


class OutputConfig(Strict):
    data_dir: Path = Field(
        Path("slrig-data"),
        description="where scans (<data_dir>/scans/<id>), calibrations, imports and the daemon's job records go",
    )


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
        8.0,
        ge=1.0,
        le=10.0,
        description="SIGTERM: the longest wait for a projector call in flight or the job's last record (a stop "
        "takes well under a second otherwise; within systemd's TimeoutStopSec=15)",
    )
    health_stale_s: float = Field(120.0, ge=5.0, le=3600.0, description="a running job silent this long is unhealthy")
    header_timeout_s: float = Field(
        10.0, ge=0.5, le=300.0, description="a connection must send its request headers within this; else closed"
    )
    body_stall_s: float = Field(10.0, ge=0.5, le=300.0, description="a request body silent this long is answered 408")
    max_connections: int = Field(
        1000,
        ge=16,
        le=100_000,
        description="open connections; past this one is closed: idle before busy, unauthenticated before "
        "authenticated, oldest first",
    )
    send_timeout_s: float = Field(
        15.0, ge=0.5, le=600.0, description="a response the client holds back is checked this often; see min_send_rate"
    )
    min_send_rate: int = Field(
        1024, ge=0, le=1_000_000_000, description="bytes/s a client must take while it holds a response back; else cut"
    )
    max_downloads: int = Field(16, ge=1, le=10_000, description="file downloads at once; more get 429")
    max_downloads_per_client: int = Field(4, ge=1, le=10_000, description="file downloads at once from one address")
    read_access: Literal["auto", "key", "open"] = Field(
        "auto",
        description="reads (GET): key: need a key (the API key or a read-only key); open: need none; "
        "auto: open on loopback, key beyond",
    )
    max_import_bytes: int = Field(
        4 * 1024**3, ge=1024**2, le=1024**4, description="bytes of one imports folder (each file: at most 64 MiB)"
    )
    max_image_pixels: int = Field(
        64_000_000, ge=1024, le=1_000_000_000, description="pixels of an uploaded frame, read from its header"
    )


class ComputeConfig(Strict):
    """Where work that needs no device may run: a Dask scheduler the daemon hands reprocessing to."""

    scheduler: str | None = Field(
        None,
        description="a running Dask scheduler (tcp://HOST:8786) whose workers see output.data_dir at the same path: "
        "the daemon's reprocessing jobs run there while its own worker keeps the rig; none: on the daemon's worker",
    )

    @field_validator("scheduler")
    @classmethod
    def _an_address(cls, value: str | None) -> str | None:
        if value is not None and not re.fullmatch(r"(tcp|tls)://(\[[0-9a-fA-F:]+\]|[^\s/:\[\]]+):[0-9]{1,5}", value):
            raise ValueError(f"{value!r} is not a Dask scheduler's address (tcp://HOST:PORT or tls://HOST:PORT)")
        return value


class RigConfig(Strict):
    """A rig description: its devices, the scene when it is simulated, and how it scans."""

    name: Name = Field("bench", description="the rig's name, shown by the daemon and kept in every manifest")
    projectors: list[ProjectorConfig] = Field(
        min_length=1, max_length=16, description="every projector, each with its driver and geometry"
    )
    cameras: list[CameraConfig] = Field(
        min_length=1, max_length=16, description="every camera, each with its driver and geometry"
    )
    simulation: SimulationConfig | None = Field(
        None, description="the simulated bench's scene; present only when every device is simulated"
    )
    scan: ScanConfig = Field(ScanConfig(), description="the codec, its settings, filters, merging, surfaces")
    calibration: CalibrationConfig = Field(
        CalibrationConfig(), description="the board, calibration sessions, and the calibration file to use"
    )
    output: OutputConfig = Field(OutputConfig(), description="where results go")
    service: ServiceConfig = Field(ServiceConfig(), description="`slrig serve`: queue, limits, connections")
    compute: ComputeConfig = Field(ComputeConfig(), description="where reprocessing without devices runs")

    @property
    def simulated(self) -> bool:
        """Its devices are the simulated bench's (then it has a `simulation` section)."""
        return self.simulation is not None

    def pair_name(self, projector: int, camera: int) -> str:
        """How stored scans name a (projector, camera) pair: `projector0_camera0`."""
        return f"{self.projectors[projector].name}_{self.cameras[camera].name}"

    @model_validator(mode="after")
    def _consistent(self) -> RigConfig:
        names = [d.name for d in (*self.projectors, *self.cameras)]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(
                f"cameras/projectors[].name: device names must be unique; repeated: {', '.join(duplicates)}"
            )
        _check_ring_model(self)
        _check_sync(self)
        _check_simulation(self)
        for k, (p, c) in enumerate(self.scan.merge.pairs or []):
            if not (0 <= p < len(self.projectors) and 0 <= c < len(self.cameras)):
                raise ValueError(f"scan.merge.pairs[{k}]: ({p}, {c}) names no projector and camera of this rig")
        _check_codec_fits(self, self.scan.codec, f"scan.{self.scan.codec}", getattr(self.scan, self.scan.codec, None))
        try:
            live = self.scan.live_params()
        except ValidationError as exc:
            found = "; ".join(validation_problems(exc))
            raise ValueError(f"scan.live.params (for codec {self.scan.live.codec}): {found}") from None
        _check_codec_fits(self, self.scan.live.codec, "scan.live", live)
        return self

    def with_codec(self, codec: str) -> RigConfig:
        """A copy that scans with `codec`, validated like the file."""
        data = self.model_dump()
        data["scan"]["codec"] = codec
        return validate_rig(data, "--codec")

    def with_exposure(self, exposure: str | None, hdr: str | None, adaptive_projection: bool = False) -> RigConfig:
        """A copy with the command line's `--exposure` (auto, camera or microseconds), `--hdr`
        (auto, a count, or microseconds separated by commas) and `--adaptive-projection`, validated
        like the file."""
        data = self.model_dump()
        chosen = data["scan"]["exposure"]
        if adaptive_projection:
            chosen["adaptive_projection"] = True
        if exposure is not None:
            named = exposure in ("auto", "camera")
            chosen["exposure"] = exposure if named else _number("--exposure", exposure, "auto, camera")
        if hdr is not None:
            if hdr == "auto" or hdr.strip().isdigit():
                chosen["hdr"] = hdr if hdr == "auto" else int(hdr)
            else:
                chosen["hdr"] = [_number("--hdr", part, "auto, a count") for part in hdr.split(",")]
        return validate_rig(data, "--exposure" if hdr is None else "--hdr")

    def with_live(self, codec: str | None, hdr: str | list[float] | None = None) -> RigConfig:
        """A copy whose live mode repeats `codec` (with scan.live's parameters when it already did)
        and, with `hdr` (auto, exposures, or the command line's microseconds separated by commas),
        at several exposures."""
        data = self.model_dump()
        if codec is not None and data["scan"]["live"]["codec"] != codec:
            data["scan"]["live"] = {**data["scan"]["live"], "codec": codec, "params": None}
        if isinstance(hdr, str) and hdr != "auto":
            hdr = [_number("--hdr", part, "auto") for part in hdr.split(",")]
        if hdr is not None:
            data["scan"]["live"]["hdr"] = hdr
        return validate_rig(data, "--codec" if hdr is None else "--hdr")

    def with_scene(self, scene: dict[str, object], source: str = "--scene") -> RigConfig:
        if self.simulation is None:
            raise ConfigError(source, ["simulation: this rig has no simulated scene to replace"])
        data = self.model_dump()
        data["simulation"]["scene"] = scene
        return validate_rig(data, source)


def _number(option: str, text: str, words: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ConfigError(option, [f"{option}: {text!r} is none of {words} or microseconds"]) from None


def validate_rig(data: object, source: str) -> RigConfig:
    """A RigConfig from data; ConfigError listing every problem, each naming its field."""
    try:
        return RigConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(source, validation_problems(exc)) from None


def _check_codec_fits(config: RigConfig, codec: str, field: str, params: object) -> None:
    """Codec parameters that only fail against a projector's size (e.g. ring spacing)."""
    for i, projector in enumerate(config.projectors):
        try:
            codec_class(codec)(projector.resolution, params)
        except ValueError as exc:
            raise ValueError(f"{field} (for projectors[{i}]): {exc}") from None


def _check_ring_model(config: RigConfig) -> None:
    model = config.scan.rings.model
    if model == "cone":
        return
    needs = {"parallel": ("orthographic", "orthographic"), "radius_ratio": ("orthographic", "pinhole")}[model]
    if any(p.geometry.projection != needs[0] for p in config.projectors) or any(
        c.geometry.projection != needs[1] for c in config.cameras
    ):
        raise ValueError(
            f"scan.rings.model: {model!r} needs {needs[0]} projectors and {needs[1]} cameras "
            "(geometry.projection); the 'cone' model works with any"
        )


def _check_sync(config: RigConfig) -> None:
    """Hardware sync: every camera's exposures must be started by the projector's trigger out."""
    if not any(p.sync == "hardware" for p in config.projectors):
        return
    for i, camera in enumerate(config.cameras):
        if not driver(DeviceKind.CAMERA, camera.driver).capabilities.trigger_input:
            cameras = drivers_of(DeviceKind.CAMERA).values()
            with_input = [e.name for e in cameras if e.capabilities.trigger_input and not e.simulated]
            raise ValueError(
                f"cameras[{i}].driver: a {camera.driver} camera has no trigger input; use sync: software "
                f"or a camera with one ({', '.join(with_input)})"
            )


def _check_simulation(config: RigConfig) -> None:
    simulated = {driver(DeviceKind.PROJECTOR, p.driver).simulated for p in config.projectors}
    simulated |= {driver(DeviceKind.CAMERA, c.driver).simulated for c in config.cameras}
    if len(simulated) > 1:
        raise ValueError(
            "projectors/cameras[].driver: simulated and real devices cannot share a rig "
            "(the simulator lights and sees only its own devices)"
        )
    if simulated == {True} and config.simulation is None:
        raise ValueError("simulation: simulated devices need a 'simulation' section with a scene")
    if simulated == {False} and config.simulation is not None:
        raise ValueError("simulation: a rig of real devices has no simulated scene; remove the section")
