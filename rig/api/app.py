"""The FastAPI application of `slrig serve`: create_app(service, settings), no module-level app."""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import AsyncIterator, Callable
from typing import Annotated, Any

from fastapi import APIRouter, FastAPI, Path, Query, Request, Response, status
from fastapi.exceptions import RequestValidationError
from fastapi.middleware.cors import CORSMiddleware
from fastapi.responses import FileResponse, JSONResponse, StreamingResponse
from fastapi.routing import APIRoute
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.middleware.trustedhost import TrustedHostMiddleware

from rig import __version__
from rig.api.aiming import aiming_router
from rig.api.bench import bench_router
from rig.api.clouds import cloud_router
from rig.api.console import add_console
from rig.api.head import HeadAsGet, head_only
from rig.api.live import live_router
from rig.api.models import (
    FILE_NAME_PATTERN,
    JOB_ID_PATTERN,
    CalibrationRequest,
    CodecView,
    Health,
    JobPage,
    JobState,
    JobView,
    Problem,
    ReprocessRequest,
    RigView,
    ScanRequest,
)
from rig.api.problems import method_not_allowed, validation_problem
from rig.api.recognition import recognition_router
from rig.api.reconstructions import reconstruction_router, upload_rule
from rig.api.security import MUTATING, READING, ApiSettings, BodyLimitMiddleware, key_role
from rig.api.sessions import Sessions, session_router
from rig.api.slots import CountedFile, Slots, client_address
from rig.api.streams import SSE_PING_S, event_slots, event_stream, sse
from rig.errors import (
    CalibrationError,
    ConfigError,
    FramesError,
    GalleryEntryNotFoundError,
    GalleryError,
    GalleryFileError,
    PatternSpecError,
    RecognitionError,
)
from rig.patterns import codec_class, codec_names
from rig.service import (
    IllegalTransitionError,
    ImportNotFoundError,
    ImportRefusedError,
    ImportTooLargeError,
    JobConflictError,
    JobNotFoundError,
    JobService,
    JobType,
    QueueFullError,
    ServiceStoppingError,
    SetupRefusedError,
    StorageFullError,
    TooManyOpenError,
)

log = logging.getLogger(__name__)

JobId = Annotated[str, Path(pattern=JOB_ID_PATTERN, description="a job id, e.g. 20261121-105227-a1b2c3")]
FileName = Annotated[str, Path(pattern=FILE_NAME_PATTERN, description="a file its result lists")]
SSE_POLL_S = 0.1
ERRORS: dict[int | str, dict[str, Any]] = {
    code: {"model": Problem} for code in (400, 401, 403, 404, 409, 413, 429, 503, 507)
}
MEDIA_TYPES = {
    ".ply": "application/octet-stream",
    ".png": "image/png",
    ".jpg": "image/jpeg",
    ".json": "application/json",
}


def _operation_id(route: APIRoute) -> str:
    return f"{route.tags[0] if route.tags else 'v1'}-{route.name}"


def create_app(service: JobService, settings: ApiSettings, stopping: Callable[[], bool] | None = None) -> FastAPI:
    """`stopping` tells event streams to end (the server is shutting down)."""
    guarded = settings.protect_reads  # beyond loopback the schema and docs need the key too
    app = FastAPI(
        title="slrig",
        version=__version__,
        description="Structured-light scans on a calibrated projector-camera rig.",
        generate_unique_id_function=_operation_id,
        openapi_url=None if guarded else "/openapi.json",
        docs_url=None,  # rig.api.console serves them without a CDN
        redoc_url=None,
    )
    app.state.api_settings = settings
    app.state.service = service
    app.state.event_streams = event_slots()
    app.state.sessions = Sessions()
    app.state.downloads = Slots("file downloads", settings.max_downloads, settings.max_downloads_per_client)
    if guarded:

        @app.get("/openapi.json", include_in_schema=False, dependencies=READING)
        def openapi() -> JSONResponse:
            return JSONResponse(app.openapi())

    is_stopping = stopping or (lambda: service.stopping)
    app.add_middleware(TrustedHostMiddleware, allowed_hosts=list(settings.allowed_hosts))
    if settings.cors_origins:
        app.add_middleware(
            CORSMiddleware, allow_origins=list(settings.cors_origins), allow_credentials=False, allow_methods=["*"]
        )
    app.add_middleware(
        BodyLimitMiddleware,
        limit=settings.max_body_bytes,
        uploads=upload_rule(service.data_dir),
        key=settings.api_key,
        stall_s=settings.body_stall_s,
    )
    _error_handlers(app)
    app.include_router(_general(service), prefix="/v1")
    app.include_router(_jobs(service, JobType.SCAN, "scans", is_stopping), prefix="/v1")
    app.include_router(_jobs(service, JobType.CALIBRATION, "calibrations", is_stopping), prefix="/v1")
    app.include_router(recognition_router(service, ERRORS), prefix="/v1")
    app.include_router(reconstruction_router(service, ERRORS), prefix="/v1")
    app.include_router(live_router(service, ERRORS, is_stopping), prefix="/v1")
    app.include_router(aiming_router(service, ERRORS), prefix="/v1")
    app.include_router(cloud_router(service, ERRORS), prefix="/v1")
    app.include_router(bench_router(service, ERRORS), prefix="/v1")
    app.include_router(session_router(ERRORS, lambda key: key_role(settings, key)), prefix="/v1")
    add_console(app, docs=not guarded)
    app.add_middleware(HeadAsGet)  # outermost: HEAD is a GET to everything inside
    return app


def _error_handlers(app: FastAPI) -> None:
    def handler(code: int, headers: dict[str, str] | None = None) -> Callable[[Request, Exception], Any]:
        async def respond(request: Request, exc: Exception) -> JSONResponse:
            return JSONResponse({"detail": str(exc)}, status_code=code, headers=headers)

        return respond

    app.add_exception_handler(JobNotFoundError, handler(404))
    app.add_exception_handler(JobConflictError, handler(409))
    app.add_exception_handler(IllegalTransitionError, handler(409))  # a damaged record's unknown state
    app.add_exception_handler(QueueFullError, handler(429, {"Retry-After": "5"}))
    app.add_exception_handler(TooManyOpenError, handler(429, {"Retry-After": "5"}))
    app.add_exception_handler(ServiceStoppingError, handler(503))
    app.add_exception_handler(StorageFullError, handler(507))  # nothing changed; free some space
    app.add_exception_handler(GalleryError, handler(409))  # a scan already in it, other settings
    app.add_exception_handler(GalleryEntryNotFoundError, handler(404))
    app.add_exception_handler(GalleryFileError, handler(503))  # not a gallery, or newer: left as it is
    app.add_exception_handler(RecognitionError, handler(422))  # too little surface, an empty gallery
    app.add_exception_handler(ImportNotFoundError, handler(404))
    app.add_exception_handler(ImportTooLargeError, handler(413))
    app.add_exception_handler(SetupRefusedError, handler(409))  # what this rig or its driver does not have

    async def config_error(request: Request, exc: Exception) -> JSONResponse:
        problems = exc.problems if isinstance(exc, (ConfigError, PatternSpecError)) else [str(exc)]
        detail = [{"loc": [p.split(":")[0]], "msg": p, "type": "config"} for p in problems]  # like FastAPI's 422
        return JSONResponse({"detail": detail}, status_code=422)

    app.add_exception_handler(RequestValidationError, validation_problem)  # renders NaN and lone surrogates too
    app.add_exception_handler(StarletteHTTPException, method_not_allowed)  # 405: Allow lists every method
    app.add_exception_handler(ConfigError, config_error)
    # what a reconstruction request names, refused in the shape of FastAPI's own 422
    for refused in (PatternSpecError, ImportRefusedError, FramesError, CalibrationError):
        app.add_exception_handler(refused, config_error)


def _general(service: JobService) -> APIRouter:
    router = APIRouter(tags=["rig"], dependencies=READING, responses=ERRORS)

    @router.get("/health", response_model=Health)
    def health() -> Health:
        problems = service.problems()
        status = "degraded" if problems else "ok"
        return Health(status=status, version=__version__, rig=service.config.name, problems=problems)

    @router.get("/rig", response_model=RigView)
    def rig_state() -> RigView:
        return RigView.model_validate(service.rig_status())

    @router.get("/codecs", response_model=list[CodecView])
    def codecs() -> list[CodecView]:
        config = service.config
        resolution = tuple(config.projectors[0].resolution)
        out = []
        for name in codec_names():
            try:
                frames = codec_class(name)(resolution, getattr(config.scan, name, None)).frame_count
            except ValueError:
                continue  # does not fit this rig's projector
            out.append(CodecView(name=name, frames=frames, default=name == config.scan.codec))
        return out

    return router


def _jobs(service: JobService, kind: JobType, collection: str, stopping: Callable[[], bool]) -> APIRouter:
    """The routes of one job collection (scans, calibrations)."""
    router = APIRouter(prefix=f"/{collection}", tags=[collection], responses=ERRORS)
    base = f"/v1/{collection}"
    _creating_routes(router, service, kind, base)
    _record_routes(router, service, kind, base)
    _result_routes(router, service, kind, stopping)
    return router


def _creating_routes(router: APIRouter, service: JobService, kind: JobType, base: str) -> None:
    """POST: a new job of this collection (and, for scans, a reprocessing of a stored one)."""

    def created(job_view: JobView, response: Response) -> JobView:
        response.headers["Location"] = job_view.links["self"]
        return job_view

    if kind is JobType.SCAN:

        @router.post("", status_code=status.HTTP_202_ACCEPTED, response_model=JobView, dependencies=MUTATING)
        def create_scan(body: ScanRequest, response: Response) -> JobView:
            job = service.submit_scan(body.model_dump(exclude_none=True))
            return created(JobView.of(job, base), response)

        @router.post(
            "/{job_id}/reprocess", status_code=status.HTTP_202_ACCEPTED, response_model=JobView, dependencies=MUTATING
        )
        def reprocess_scan(job_id: JobId, body: ReprocessRequest, response: Response) -> JobView:
            job = service.submit_reprocess(job_id, body.model_dump(exclude_none=True))
            return created(JobView.of(job, base), response)

    else:

        @router.post("", status_code=status.HTTP_202_ACCEPTED, response_model=JobView, dependencies=MUTATING)
        def create_calibration(body: CalibrationRequest, response: Response) -> JobView:
            job = service.submit_calibration(body.model_dump(exclude_none=True))
            return created(JobView.of(job, base), response)


def _record_routes(router: APIRouter, service: JobService, kind: JobType, base: str) -> None:
    """The job records: list, get, delete, cancel."""

    @router.get("", response_model=JobPage, dependencies=READING)
    def list_jobs(
        limit: Annotated[int, Query(ge=1, le=100)] = 20,
        offset: Annotated[int, Query(ge=0, le=1_000_000)] = 0,
        state: JobState | None = None,
    ) -> JobPage:
        jobs, total = service.store.list(kind, state, limit, offset)
        return JobPage(items=[JobView.of(j, base) for j in jobs], total=total, limit=limit, offset=offset)

    @router.get("/{job_id}", response_model=JobView, dependencies=READING)
    def get_job(job_id: JobId) -> JobView:
        return JobView.of(service.job(job_id, kind), base)

    @router.delete("/{job_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=MUTATING)
    def delete_job(job_id: JobId) -> Response:
        service.delete(job_id, kind)
        return Response(status_code=status.HTTP_204_NO_CONTENT)

    @router.post(
        "/{job_id}/cancel",
        response_model=JobView,
        dependencies=MUTATING,
        responses={202: {"model": JobView, "description": "running: it stops at its next step"}},
    )
    def cancel_job(job_id: JobId, response: Response) -> JobView:
        job = service.cancel(job_id, kind)
        if job.state is JobState.RUNNING:
            response.status_code = status.HTTP_202_ACCEPTED
        return JobView.of(job, base)


def _result_routes(router: APIRouter, service: JobService, kind: JobType, stopping: Callable[[], bool]) -> None:
    """What a job gives: its files, and its events as they happen."""

    @router.get(
        "/{job_id}/files/{name}",
        dependencies=READING,
        response_class=FileResponse,
        responses={200: {"content": {"application/octet-stream": {}, "image/png": {}, "application/json": {}}}},
    )
    def download(job_id: JobId, name: FileName, request: Request) -> FileResponse:
        """The file, whole or the byte ranges asked for (Range); at most service.max_downloads at
        once (max_downloads_per_client from one address), more: 429."""
        path = service.file_path(job_id, kind, name)
        slots: Slots = request.app.state.downloads
        release = (lambda: None) if head_only(request.scope) else slots.take(client_address(request.client))
        media = MEDIA_TYPES.get(path.suffix, "application/octet-stream")
        return CountedFile(release, path, media_type=media, filename=name)

    @router.get(
        "/{job_id}/events",
        dependencies=READING,
        response_class=StreamingResponse,
        responses={200: {"content": {"text/event-stream": {}}, "description": "state and progress events"}},
    )
    async def events(job_id: JobId, request: Request) -> StreamingResponse:
        await asyncio.to_thread(service.job, job_id, kind)  # 404 before the stream starts
        try:
            last = max(0, int(request.headers.get("last-event-id", "0")))
        except ValueError:
            last = 0
        return event_stream(request, lambda: _event_stream(service, job_id, last, request, stopping))


async def _event_stream(
    service: JobService, job_id: str, last: int, request: Request, stopping: Callable[[], bool]
) -> AsyncIterator[bytes]:
    """Events after `last` until the job ends; a job whose events are gone gets its state."""
    idle, polls = 0.0, 0
    while not stopping() and not await request.is_disconnected():
        fresh = service.events.since(job_id, last)
        for event in fresh:
            last = event.id
            yield sse(event.type, json.dumps(event.data), event.id)
            if event.type == "state" and event.data["state"] not in (JobState.QUEUED, JobState.RUNNING):
                return
        if fresh:
            idle = 0.0
            continue
        idle += SSE_POLL_S
        if idle >= SSE_PING_S:
            idle = 0.0
            yield b": ping\n\n"
        polls += 1
        if polls % 10 == 1:  # at once, then about every second: did it end unseen (events evicted)?
            try:
                job = await asyncio.to_thread(service.store.get, job_id)
            except JobNotFoundError:
                job = None
            if job is None or job.terminal or job.state is None:  # None: a damaged record, which never moves
                data = {"id": job_id, "state": job.state if job else "deleted", "error": job.error if job else None}
                yield sse("state", json.dumps(data))
                return
        await asyncio.sleep(SSE_POLL_S)
