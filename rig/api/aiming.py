"""Setting up the bench over REST: aim mode (POST/DELETE/GET /v1/aim: the projectors show a setup
pattern while the cameras run), each camera's settings (GET /v1/cameras, PUT
/v1/cameras/{camera}/settings) and its newest frame (GET /v1/cameras/{camera}/frame.jpg).

A frame request names the last frame its client has (`after`) and is answered once a newer one
exists (or 204 after `wait_s`, and at once while nothing captures): a client asks for the next
when it has shown the last, so a slow one gets fewer frames, and the rig never waits for any
(rig.service.frames).
"""

from __future__ import annotations

import asyncio
import time
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query, Request, Response, status
from pydantic import BaseModel, Field

from rig.api.frame_views import FrameViews
from rig.api.models import CodecName, _Request
from rig.api.security import MUTATING, READING
from rig.api.slots import Slots, client_address
from rig.patterns import SETUP_PATTERNS
from rig.service import AimRequest, JobService, SetupRefusedError, TappedFrame

Errors = dict[int | str, dict[str, Any]]
CameraIndex = Annotated[int, Path(ge=0, le=15, description="the camera's index in the config")]
PatternName = Literal[(*SETUP_PATTERNS, "codec")]  # type: ignore[valid-type]
MAX_FRAME_WAITERS = 32
JOB_VIEW_RATE = 5.0  # frames a second per camera for the viewers while a job runs


class AimStart(_Request):
    pattern: PatternName = Field("white", description="a setup pattern, or `codec`: pattern `index` of `codec`")
    projector: int | None = Field(None, ge=0, le=15, description="the projector that shows it (others dark); all")
    square_px: int = Field(32, ge=1, le=4096, description="checkerboard square, projector pixels")
    codec: CodecName | None = Field(None, description="with pattern codec; default: the config's")
    index: int = Field(0, ge=0, le=100_000, description="with pattern codec: which of its patterns")
    seconds: float = Field(60.0, gt=0, le=3600, description="dark again after this long unless renewed")


class AimView(BaseModel):
    state: Literal["off", "starting", "running", "paused", "failed"]
    reason: str | None
    pattern: dict[str, Any] | None
    seconds_left: float | None


class CameraSettingsRequest(_Request):
    exposure_us: float | None = Field(None, ge=1, le=10_000_000, description="manual exposure, microseconds")
    gain: float | None = Field(None, ge=0, le=64, description="analogue gain (the driver's units; OAK: ISO/100)")


class CameraView(BaseModel):
    index: int
    name: str
    driver: str
    resolution: list[int]
    exposure_us: float
    gain: float | None = Field(description="none: the driver leaves it as the camera has it")
    has_gain: bool | None = Field(description="the driver has a gain control (none: the rig has not been opened)")
    frame: int | None = Field(description="the newest frame's number (frame.jpg?after= it waits for a newer)")
    fps: float = Field(description="frames per second reaching the daemon now")


def aiming_router(service: JobService, errors: Errors) -> APIRouter:
    router = APIRouter(tags=["aim"], responses=errors)
    _aim_routes(router, service)
    _camera_routes(router, service)
    return router


def _aim_routes(router: APIRouter, service: JobService) -> None:
    @router.post("/aim", status_code=status.HTTP_202_ACCEPTED, response_model=AimView, dependencies=MUTATING)
    def start_aim(body: AimStart) -> dict[str, Any]:
        fields = body.model_dump(exclude={"seconds"})
        live = service.live.view()["state"] in ("starting", "running")
        return service.aim.start(AimRequest(**fields), body.seconds, live)

    @router.delete("/aim", response_model=AimView, dependencies=MUTATING)
    def stop_aim() -> dict[str, Any]:
        return service.aim.stop()

    @router.get("/aim", response_model=AimView, dependencies=READING)
    def aim_status() -> dict[str, Any]:
        return service.aim.view()


def _camera_routes(router: APIRouter, service: JobService) -> None:
    views = FrameViews()
    waiters = Slots("frame requests", MAX_FRAME_WAITERS, 8)

    def camera_views() -> list[dict[str, Any]]:
        out = service.camera_settings.views(service.open_rig)
        for view in out:
            newest = service.frames.newest(view["index"])
            view["frame"] = None if newest is None else newest.count
            view["fps"] = round(service.frames.rate(view["index"]), 2)
        return out

    @router.get("/cameras", response_model=list[CameraView], dependencies=READING)
    def cameras() -> list[dict[str, Any]]:
        return camera_views()

    @router.put("/cameras/{camera}/settings", response_model=CameraView, dependencies=MUTATING)
    def camera_settings(camera: CameraIndex, body: CameraSettingsRequest) -> dict[str, Any]:
        if camera >= len(service.config.cameras):
            raise SetupRefusedError(f"camera: this rig has {len(service.config.cameras)} cameras")
        values = body.model_dump(exclude_none=True)
        service.camera_settings.request(camera, values, service.busy_with)
        return camera_views()[camera]

    @router.get(
        "/cameras/{camera}/frame.jpg",
        dependencies=READING,
        responses={200: {"content": {"image/jpeg": {}}}, 204: {"description": "no newer frame within wait_s"}},
    )
    async def camera_frame(
        camera: CameraIndex,
        request: Request,
        after: Annotated[int, Query(ge=0, description="the newest frame number the client has")] = 0,
        width: Annotated[int | None, Query(ge=16, le=8192, description="downscale to this width")] = None,
        overlay: Annotated[bool, Query(description="saturated pixels red, too-dark ones blue")] = False,
        wait_s: Annotated[float, Query(ge=0, le=10, description="how long to wait for a newer frame")] = 2.0,
    ) -> Response:
        if camera >= len(service.config.cameras):
            raise SetupRefusedError(f"camera: this rig has {len(service.config.cameras)} cameras")
        busy = service.busy_with  # read once: frames while a job runs are fewer and plainer
        if busy is None and not _mode_capturing(service):  # nothing will come: say so at once, not after wait_s
            headers = {"Cache-Control": "no-store", "X-Reason": "nothing captures: start aim mode, live mode or a scan"}
            return Response(status_code=status.HTTP_204_NO_CONTENT, headers=headers)
        release = waiters.take(client_address(request.client))
        try:
            tapped = await _newer_frame(service, views, camera, after, wait_s, busy is not None)
            if tapped is None:
                return Response(status_code=status.HTTP_204_NO_CONTENT, headers={"Cache-Control": "no-store"})
            view = await asyncio.to_thread(views.view, camera, tapped, width, overlay, busy is None)
        finally:
            release()
        return Response(view.jpeg, media_type="image/jpeg", headers=view.headers)


async def _newer_frame(
    service: JobService, views: FrameViews, camera: int, after: int, wait_s: float, job: bool
) -> TappedFrame | None:
    """The newest frame after `after`; while a `job` runs, at most JOB_VIEW_RATE a second per
    camera are encoded (whatever the clients ask), so viewers cost the scan little."""
    tapped = await service.frames.next_after(camera, after, wait_s)
    wait = views.last_encoded(camera) + 1.0 / JOB_VIEW_RATE - time.monotonic()
    if tapped is not None and wait > 0 and job:
        await asyncio.sleep(wait)
        tapped = service.frames.newest(camera) or tapped  # the newest by then
    return tapped


def _mode_capturing(service: JobService) -> bool:
    """Whether aim or live mode is wanted (then frames are coming)."""
    modes = (service.aim.view()["state"], service.live.state()[0])
    return any(state in ("starting", "running") for state in modes)
