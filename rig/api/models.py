"""Request and response bodies of the REST API (pydantic; unknown fields are errors)."""

from __future__ import annotations

import datetime as dt
import re
import typing
from types import UnionType
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, ValidationInfo, field_validator, model_validator
from pydantic.json_schema import SkipJsonSchema

from rig.config import DeviceKind, ExposureUs
from rig.patterns import codec_names
from rig.recognition import LABEL
from rig.service import JOB_ID, Job, JobState, JobType
from rig.store import json_problem

JOB_ID_PATTERN = JOB_ID.pattern
FILE_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$"
LABEL_PATTERN = f"^{LABEL.pattern}$"
CodecName = Literal[tuple(codec_names())]  # type: ignore[valid-type]


MAX_REST_VIEWS = 40  # about 3 s of capture and analysis per view of the default bench


class _Request(BaseModel):
    """A request body: strict types (no `true` for a number, no "1" for an integer), and nothing
    anywhere in it, free-form objects included, that could not be stored and served back
    (rig.store.portable: finite numbers, no lone surrogates, bounded depth and size)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)

    @field_validator("*", mode="before")
    @classmethod
    def _portable(cls, value: Any, info: ValidationInfo) -> Any:
        problem = json_problem(value, info.field_name or "")
        if problem:
            raise ValueError(problem)
        if isinstance(value, float) and value.is_integer() and _integer_field(cls, info.field_name):
            return int(value)  # JSON Schema's integer includes 11.0; strict mode alone would refuse it
        return value


def _integer_field(model: type[BaseModel], name: str | None) -> bool:
    annotation = model.model_fields[name].annotation if name in model.model_fields else None
    kinds = set(typing.get_args(annotation)) if typing.get_origin(annotation) in (Union, UnionType) else {annotation}
    kinds = {typing.get_args(k)[0] if typing.get_origin(k) is Annotated else k for k in kinds}  # Annotated[int, ...]
    return int in kinds and float not in kinds


class ScanRequest(_Request):
    codec: CodecName | None = Field(
        None, description="a codec (GET /v1/codecs lists this rig's); default: the config's"
    )
    keep_frames: bool = Field(False, description="store the raw frames, so the scan can be reprocessed")
    label: str | None = Field(None, max_length=200, description="free text kept with the scan")
    adaptive: bool = Field(
        False,
        description="a dense pilot scan, a ring plan from it, then the planned rings (the manifest keeps the plan)",
    )
    tolerance_mm: float | None = Field(
        None,
        gt=0,
        le=100,
        description="adaptive: the surface within this of the object on tolerance_quantile of every region's area; "
        "default: scan.adaptive's",
    )
    tolerance_quantile: float | None = Field(
        None, ge=0.5, le=1.0, description="adaptive: the share of every region's area within tolerance_mm (0.95)"
    )
    plan: dict[str, Any] | None = Field(
        None,
        description="a ring plan (as `slrig plan rings --out` writes it, or a manifest's adaptive.plan): its rings",
    )
    exposure: ExposureUs | Literal["auto", "camera"] | None = Field(
        None, description="auto, camera, or microseconds for every camera; default: scan.exposure's"
    )
    hdr: Annotated[int, Field(ge=2, le=10)] | Literal["auto"] | list[ExposureUs] | None = Field(
        None,
        description="several exposures merged per pixel: auto, a count, or 2 to 10 exposures in microseconds; "
        "default: scan.exposure's",
    )
    adaptive_projection: bool | None = Field(
        None,
        description="dim the patterns where the cameras would clip, from a pre-scan at a short exposure; "
        "default: scan.exposure's",
    )


class ReprocessRequest(_Request):
    calibration: str | None = Field(
        None, pattern=JOB_ID_PATTERN, description="a finished calibration's id; default: the scan's own geometry"
    )
    max_depth_jump_mm: float | None = Field(
        None, gt=0, le=1000, description="depth-jump filter for dense codecs; default: the scan's setting"
    )
    label: str | None = Field(None, max_length=200)


class ReconstructionRequest(_Request):
    frames: str = Field(pattern=FILE_NAME_PATTERN, description="the imports folder holding the frames")
    patterns: dict[str, Any] | str = Field(
        description="the pattern description (as in slrig reconstruct's YAML), or a YAML file's name in the folder"
    )
    calibration: (
        Annotated[str, StringConstraints(pattern=FILE_NAME_PATTERN)]
        | Annotated[
            list[Annotated[str, StringConstraints(pattern=FILE_NAME_PATTERN)]], Field(min_length=1, max_length=4)
        ]
    ) = Field(
        description="a finished calibration's id, a calibration file's name in the folder, or the names of the "
        "files of one calibration read together (OpenCV's intrinsics.yml and extrinsics.yml)"
    )
    calibration_options: dict[str, Any] | None = Field(
        None, description="what a foreign calibration file does not say (as slrig reconstruct's options)"
    )
    label: str | None = Field(None, max_length=200)


class GalleryAddRequest(_Request):
    scan_id: str = Field(pattern=JOB_ID_PATTERN, description="a finished scan's id")
    label: str = Field(pattern=LABEL_PATTERN, description="a plain name: letters, digits, '.', '_', '-'")
    rings: int | None = Field(None, ge=1, le=64, description="descriptor rings (first entry only; default 8)")
    samples: int | None = Field(None, ge=8, le=1024, description="samples per ring, even (first entry only; 64)")
    inner_mm: float | None = Field(None, gt=0, le=500, description="the innermost ring's radius (first entry only; 6)")
    outer_mm: float | None = Field(None, gt=0, le=500, description="the outermost ring's radius (first entry only; 48)")
    distance: Literal["geodesic", "euclidean"] | None = None
    spectrum: Literal["per_ring", "concatenated"] | None = None
    frame: Literal["balanced", "viewer"] | None = None


class IdentifyRequest(_Request):
    top: int = Field(5, ge=1, le=100, description="labels to return")
    threshold: float | None = Field(
        None, ge=-1, le=1, description="below this score: unknown (default: per comparison, from the benchmark's EER)"
    )
    comparison: Literal["standardised", "raw"] = "standardised"


class CalibrationRequest(_Request):
    model_config = ConfigDict(
        json_schema_extra={
            # what _consistent refuses, said in the schema too, so a client (or a generator) knows it
            "dependentRequired": {"patterns": ["images"], "view_glob": ["patterns"], "board_image": ["patterns"]},
            "not": {
                "anyOf": [
                    {"required": ["images", "views"]},
                    {"required": ["what", "images"], "properties": {"what": {"const": "response"}}},
                    {"required": ["what", "board"], "properties": {"what": {"const": "response"}}},
                    {"required": ["what", "model"], "properties": {"what": {"const": "response"}}},
                ]
            },
        }
    )
    what: Literal["camera", "projector", "rig", "response"] = "rig"
    views: int | None = Field(
        None,
        ge=3,
        le=MAX_REST_VIEWS,
        description=f"views to capture (default: the config's, at most {MAX_REST_VIEWS}): one request holds the "
        "rig for minutes at most; longer sessions from the CLI",
    )
    images: Annotated[str, StringConstraints(pattern=FILE_NAME_PATTERN)] | SkipJsonSchema[None] = Field(
        None,
        description="calibrate from this imports folder's captures instead of capturing (no device is opened): one "
        "sub-folder per board pose, in the bench's own layout (view_NN/<camera>.png, view_NN/<projector>_<camera>/"
        "NNN.png, as `slrig calibrate --save-views` writes it) or, with `patterns`, another system's",
    )
    patterns: dict[str, Any] | str | SkipJsonSchema[None] = Field(
        None,
        description="with images: another system's captures, each view's frames as this pattern description lists "
        "them (as in slrig reconstruct's YAML), or a YAML file's name in the folder",
    )
    view_glob: str = Field(
        "*", pattern=r"^[A-Za-z0-9_.*?\[\]-]{1,100}$", description="with patterns: the sub-folders that are views"
    )
    board_image: Literal["auto", "white", "mean", "modulation"] = Field(
        "auto", description="with patterns: where the board is found (auto: the white frame, else the frames' mean)"
    )
    board: Annotated[str, StringConstraints(max_length=100)] | SkipJsonSchema[None] = Field(
        None,
        description="the board as KIND:COLSxROWS:SQUARE_MM[:MARKER_MM[:DICTIONARY]] (squares, not inner corners), "
        "e.g. checker:10x8:75; default: the config's calibration.board",
    )
    model: Annotated[str, StringConstraints(max_length=100)] | SkipJsonSchema[None] = Field(
        None, description="the lens model (as calibration.model); default: the config's"
    )
    camera_model: Annotated[str, StringConstraints(max_length=100)] | SkipJsonSchema[None] = Field(
        None, description="the cameras' own lens model (as calibration.camera_model); default: model's"
    )
    projector_model: Annotated[str, StringConstraints(max_length=100)] | SkipJsonSchema[None] = Field(
        None, description="the projectors' own lens model (as calibration.projector_model); default: model's"
    )
    world: Literal["board", "camera"] | SkipJsonSchema[None] = Field(
        None,
        description="the frame the calibration is written in: board (the first view's board) or camera (the first "
        "camera's); default: the config's calibration.world. A simulated rig scans in the board's",
    )

    @field_validator("images", "patterns", "board", "model", "camera_model", "projector_model", "world", mode="before")
    @classmethod
    def _not_null(cls, value: Any, info: ValidationInfo) -> Any:
        if value is None:  # the schema has no null: leave the field out for the default
            raise ValueError(f"{info.field_name}: null; leave it out for the default")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> CalibrationRequest:
        if self.images is None and self.patterns is not None:
            raise ValueError("patterns: only with images (the imports folder of the captures it describes)")
        for name in ("view_glob", "board_image"):
            if name in self.model_fields_set and self.patterns is None:
                raise ValueError(f"{name}: only with patterns (another system's captures)")
        for name in ("board", "model"):
            if self.what == "response" and getattr(self, name) is not None:
                raise ValueError(f"{name}: a response measurement uses no board and no lens model")
        if self.images is not None and self.what == "response":
            raise ValueError("images: a response measurement projects its own patterns; it takes no captures")
        if self.images is not None and self.views is not None:
            raise ValueError("views: the captures in images are the views; views is for capturing")
        return self


class JobView(BaseModel):
    id: str
    kind: JobType
    state: JobState | None = Field(description="none only for a damaged record whose state is unreadable")
    created: dt.datetime
    started: dt.datetime | None
    finished: dt.datetime | None
    stage: str | None
    fraction: float
    error: str | None
    request: dict[str, Any]
    result: dict[str, Any] | None
    problem: str | None = Field(
        None,
        description="a damaged record (an older version's, a bug's, a hand edit's): what of it cannot be shown; "
        "it can be deleted, and `slrig store check --repair` quarantines it",
    )
    links: dict[str, str]

    @classmethod
    def of(cls, job: Job, base: str) -> JobView:
        def when(t: float | None) -> dt.datetime | None:  # job_from_row checked that it is a time
            return None if t is None else dt.datetime.fromtimestamp(t, dt.UTC)

        links = {"self": f"{base}/{job.id}", "events": f"{base}/{job.id}/events"}
        files = (job.result or {}).get("files", [])
        if job.state is JobState.DONE and isinstance(files, list):
            for name in files:
                if isinstance(name, str) and re.fullmatch(FILE_NAME_PATTERN, name):
                    links[name] = f"{base}/{job.id}/files/{name}"
        return cls(
            id=job.id,
            kind=job.kind,
            state=job.state,
            created=when(job.created),  # type: ignore[arg-type]
            started=when(job.started),
            finished=when(job.finished),
            stage=job.stage,
            fraction=job.fraction,
            error=job.error,
            request=job.request,
            result=job.result,
            problem=job.problem,
            links=links,
        )


class JobPage(BaseModel):
    items: list[JobView]
    total: int
    limit: int
    offset: int


class Health(BaseModel):
    status: Literal["ok", "degraded"]
    version: str
    rig: str
    problems: list[str] = Field(default_factory=list, description="why the service is degraded")


class DeviceView(BaseModel):
    name: str
    kind: DeviceKind
    driver: str
    resolution: list[int] | None = Field(description="pixels (width, height); none for a power control")
    open: bool


class QueueView(BaseModel):
    queued: int
    max: int


class RigView(BaseModel):
    name: str
    simulated: bool
    state: Literal["idle", "busy", "live", "aim", "fault"]
    running: str | None
    last_error: str | None
    queue: QueueView
    devices: list[DeviceView]


class CodecView(BaseModel):
    name: str
    frames: int
    default: bool


class Problem(BaseModel):
    detail: str


class LiveRequest(_Request):
    codec: CodecName | None = Field(None, description="the codec live mode repeats; default: scan.live's")
    seconds: float | None = Field(None, gt=0, le=86400, description="stop after this long; default: when stopped")
    hdr: Literal["auto"] | list[ExposureUs] | None = Field(
        None,
        description="every sequence at several exposures, merged per pixel: auto (bracketed once at the start) "
        "or 2 to 4 exposures in microseconds; default: scan.live's",
    )


class LiveLatency(BaseModel):
    median: float
    p95: float
    max: float


class LiveView(BaseModel):
    state: Literal["off", "starting", "running", "paused", "failed"] = Field(
        description="paused: a job is running (live mode resumes after it); failed: see reason"
    )
    reason: str | None
    session: int = Field(description="counts live sessions; a new codec starts a new one")
    codec: str
    params: dict[str, Any]
    hdr: Literal["auto"] | list[float] | None = Field(None, description="the exposures each sequence is taken at")
    seconds_left: float | None = Field(description="until its time limit; none: until stopped")
    sequences: int = Field(description="the number of this session's newest reconstructed sequence")
    dropped: int = Field(0, description="sequences captured but dropped whole: the machine fell behind")
    seconds: float = Field(description="from the session's first sequence to its latest")
    clouds_per_s: float = Field(description="over the last 32 sequences")
    latency_ms: LiveLatency | None = Field(description="from a sequence's last frame to its depth images")
    sequence_ms_median: float | None
    points: int = Field(description="points of the latest sequence")
