"""The recognition routes: the gallery (list, add a finished scan, delete an entry) and the
identification of a finished scan. Gallery changes are serialised by one lock."""

from __future__ import annotations

import threading
from pathlib import Path as FilePath
from typing import Annotated, Any

from fastapi import APIRouter, Path, Response, status

from rig.api.models import JOB_ID_PATTERN, GalleryAddRequest, IdentifyRequest
from rig.api.security import MUTATING, READING
from rig.recognition import Gallery
from rig.service import (
    JobConflictError,
    JobService,
    JobState,
    JobType,
    gallery_add,
    gallery_path,
    identify_scan,
    settings_from,
)

JobId = Annotated[str, Path(pattern=JOB_ID_PATTERN, description="a finished scan's id")]
EntryId = Annotated[int, Path(ge=1, le=2**62, description="a gallery entry's id")]


def recognition_router(service: JobService, errors: dict[int | str, dict[str, Any]]) -> APIRouter:
    router = APIRouter(tags=["recognition"], responses=errors)
    lock = threading.Lock()
    path = gallery_path(service.data_dir)

    def scan_folder(scan_id: str) -> FilePath:
        job = service.job(scan_id, JobType.SCAN)
        if job.state is not JobState.DONE:
            raise JobConflictError(f"scan {scan_id} is {job.state}; only a finished scan can be described")
        return service.job_folder(job)

    @router.get("/gallery", dependencies=READING)
    def list_gallery() -> dict[str, Any]:
        with Gallery(path) as gallery:
            settings = gallery.settings()
            return {
                "settings": None if settings is None else settings.as_dict(),
                "entries": [e.as_dict() for e in gallery.entries()],
            }

    @router.post("/gallery", status_code=status.HTTP_201_CREATED, dependencies=MUTATING)
    def add_to_gallery(body: GalleryAddRequest, response: Response) -> dict[str, Any]:
        folder = scan_folder(body.scan_id)
        options = body.model_dump(include={"rings", "samples", "inner_mm", "outer_mm", "distance", "spectrum", "frame"})
        with lock, Gallery(path) as gallery:
            entry = gallery_add(gallery, folder, body.label, settings_from(options))
        response.headers["Location"] = f"/v1/gallery/{entry.id}"
        return entry.as_dict()

    @router.delete("/gallery/{entry_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=MUTATING)
    def delete_entry(entry_id: EntryId) -> Response:
        with lock, Gallery(path) as gallery:
            gallery.remove(entry_id)
        return Response(status_code=status.HTTP_204_NO_CONTENT)

    @router.post("/scans/{scan_id}/identify", dependencies=MUTATING)
    def identify(scan_id: JobId, body: IdentifyRequest) -> dict[str, Any]:
        folder = scan_folder(scan_id)
        with Gallery(path) as gallery:
            _, found = identify_scan(gallery, folder, body.top, body.threshold, body.comparison)
        return {"scan_id": scan_id, **found.as_dict()}

    return router
