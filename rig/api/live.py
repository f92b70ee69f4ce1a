"""Live mode over REST: POST /v1/live starts it, DELETE stops it, GET streams it (server-sent
events: a `state` event when it changes, a `depth` event per sequence a client is ready for),
GET /v1/live/status reports it and GET /v1/live/depth.png gives the newest depth image.

Each stream sends the newest frame whenever its client has taken the previous one, so a slow
client skips sequences; the rig never waits for a client (rig.service.live). A stream ends when
live mode stops (a browser's EventSource reconnects by itself).
"""

from __future__ import annotations

import asyncio
import base64
import json
import threading
from collections.abc import AsyncIterator, Callable
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response, status
from fastapi.responses import StreamingResponse

from rig.api.models import LiveRequest, LiveView
from rig.api.security import MUTATING, READING
from rig.api.streams import SSE_PING_S, event_stream, sse
from rig.pipeline import LiveFrame
from rig.service import JobNotFoundError, JobService, ServiceStoppingError
from rig.store import depth_colour_jpeg, depth_image_png

LIVE_POLL_S = 0.01  # a stream looks for a newer frame this often
DEPTH_UNIT_MM = 0.1  # live depth PNGs count tenths of a millimetre (to 6.5 m)
ENDED = ("off", "failed")  # a stream ends with live mode
RECONNECT_MS = 2000

Stride = Annotated[int, Query(ge=1, le=16, description="send every stride-th pixel of each row and column")]
Camera = Annotated[int, Query(ge=0, le=15, description="the camera's index in the config")]
Colour = Annotated[bool, Query(description="depth as a colour-mapped JPEG to look at (jpeg_base64, range_mm)")]


Errors = dict[int | str, dict[str, Any]]


def live_router(service: JobService, errors: Errors, stopping: Callable[[], bool]) -> APIRouter:
    router = APIRouter(prefix="/live", tags=["live"], responses=errors)
    encoded = _EncodedFrames()

    @router.post("", status_code=status.HTTP_202_ACCEPTED, response_model=LiveView, dependencies=MUTATING)
    def start_live(body: LiveRequest) -> dict[str, Any]:
        if service.stopping:
            raise ServiceStoppingError("the daemon is shutting down")
        return service.live.start(body.codec, body.seconds, body.hdr)

    @router.delete("", response_model=LiveView, dependencies=MUTATING)
    def stop_live() -> dict[str, Any]:
        return service.live.stop()

    @router.get("/status", response_model=LiveView, dependencies=READING)
    def live_status() -> dict[str, Any]:
        return service.live.view()

    @router.get(
        "",
        dependencies=READING,
        response_class=StreamingResponse,
        responses={200: {"content": {"text/event-stream": {}}, "description": "state and depth events"}},
    )
    async def watch_live(request: Request, stride: Stride = 4, colour: Colour = False) -> StreamingResponse:
        form = (stride, colour)
        return event_stream(request, lambda: _live_stream(service, encoded, form, request, stopping))

    @router.get("/depth.png", dependencies=READING, responses={200: {"content": {"image/png": {}}}})
    async def live_depth(camera: Camera = 0) -> Response:
        _, frame = service.live.latest
        if frame is None:
            raise JobNotFoundError("live mode has no depth image yet; POST /v1/live starts it")
        if camera >= len(frame.depths):
            raise JobNotFoundError(f"camera {camera}: this rig has {len(frame.depths)} cameras")
        png = await asyncio.to_thread(depth_image_png, frame.depths[camera], DEPTH_UNIT_MM)
        headers = {"X-Depth-Unit-Mm": str(DEPTH_UNIT_MM), "X-Live-Sequence": str(frame.sequence)}
        return Response(png, media_type="image/png", headers=headers)

    return router


class _EncodedFrames:
    """The newest frame's depth event per stride, encoded once however many clients watch."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._frame: LiveFrame | None = None
        self._events: dict[tuple[int, bool], str] = {}

    def event(self, service: JobService, frame: LiveFrame, form: tuple[int, bool]) -> str:
        with self._lock:
            if frame is not self._frame:
                self._frame, self._events = frame, {}
            if form not in self._events:
                self._events[form] = json.dumps(_depth_event(service, frame, *form))
            return self._events[form]


def _depth_event(service: JobService, frame: LiveFrame, stride: int, colour: bool = False) -> dict[str, Any]:
    cameras = []
    for config, depth in zip(service.config.cameras, frame.depths, strict=True):
        sampled = depth[::stride, ::stride]
        image: dict[str, Any] = {"name": config.name, "width": sampled.shape[1], "height": sampled.shape[0]}
        if colour:
            jpeg, range_mm = depth_colour_jpeg(sampled)
            image |= {"jpeg_base64": base64.b64encode(jpeg).decode("ascii"), "range_mm": range_mm}
        else:
            image["png_base64"] = base64.b64encode(depth_image_png(sampled, DEPTH_UNIT_MM)).decode("ascii")
        cameras.append({**image, "stride": stride})
    return {
        "sequence": frame.sequence,
        "points": frame.points,
        "latency_ms": round(frame.latency_ms, 2),
        "sequence_ms": round(frame.sequence_ms, 1),
        "dropped": service.live.dropped(),  # whole sequences the machine fell behind on, so far
        "depth_unit_mm": DEPTH_UNIT_MM,
        "cameras": cameras,
    }


async def _live_stream(
    service: JobService,
    encoded: _EncodedFrames,
    form: tuple[int, bool],
    request: Request,
    stopping: Callable[[], bool],
) -> AsyncIterator[bytes]:
    """State changes and, whenever the client has taken the last one, the newest depth frame;
    the stream ends when live mode is off or has failed (at once, if it is off already)."""
    told: tuple[str, str | None, int] | None = None
    sent: tuple[int, int] = (0, 0)  # (session, sequence)
    idle = 0.0
    while not stopping() and not await request.is_disconnected():
        state = service.live.state()
        if state != told:
            told, idle = state, 0.0
            yield sse("state", json.dumps(service.live.view()))
            if state[0] in ENDED:  # an EventSource reconnects after `retry` ms, to find it started
                yield f"retry: {RECONNECT_MS}\n\n".encode()
                return
        session, frame = service.live.latest
        if frame is not None and (session, frame.sequence) != sent:
            data = await asyncio.to_thread(encoded.event, service, frame, form)
            sent, idle = (session, frame.sequence), 0.0
            yield sse("depth", data, frame.sequence)
            continue
        await asyncio.sleep(LIVE_POLL_S)
        idle += LIVE_POLL_S
        if idle >= SSE_PING_S:
            idle = 0.0
            yield b": ping\n\n"
