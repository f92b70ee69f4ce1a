"""Reconstruction of another system's frames over REST: upload the frames (and the description or
calibration file, where they are files) into an imports folder, then ask for a reconstruction; the
result is a scan like any other (listed, downloaded, identified under /v1/scans). Calibration
captures are uploaded the same way, one sub-folder per view, for POST /v1/calibrations' `images`."""

from __future__ import annotations

from pathlib import Path as FsPath
from typing import Annotated, Any

from fastapi import APIRouter, Path, Request, Response, status
from starlette.concurrency import run_in_threadpool

from rig.api.models import FILE_NAME_PATTERN, JobView, ReconstructionRequest
from rig.api.security import MUTATING, READING, UploadRule
from rig.service import (
    MAX_DEPTH,
    MAX_FILE_BYTES,
    SUFFIXES,
    JobService,
    StorageFullError,
    check_free_space,
    list_imports,
    remove_folder,
    store_file,
)

Name = Annotated[str, Path(pattern=FILE_NAME_PATTERN, description="a plain name: letters, digits, '_', '.', '-'")]
_SUFFIXES = "|".join(s.lstrip(".") for s in SUFFIXES)
UploadName = Annotated[
    str,
    Path(
        pattern=rf"^([A-Za-z0-9][A-Za-z0-9_.-]{{0,99}}/){{0,{MAX_DEPTH}}}"
        rf"[A-Za-z0-9][A-Za-z0-9_.-]{{0,94}}\.({_SUFFIXES}|{_SUFFIXES.upper()})$",
        description="a plain file name with the suffix of a frame, a description or a calibration; for "
        f"calibration captures, behind at most {MAX_DEPTH} sub-folders (view_00/cam0.png)",
    ),
]
BINARY_BODY = {
    "requestBody": {
        "required": True,
        "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    }
}
UPLOADS = "/v1/imports/"


def upload_rule(data_dir: FsPath) -> UploadRule:
    """Uploads' body limit, and a declared size the disk cannot take refused before it is read."""

    def refusal(declared: int) -> tuple[int, str] | None:
        if declared == 0:
            return 422, "the request body is empty; it must hold the file's bytes"
        try:
            check_free_space(data_dir, declared, "this upload")
        except StorageFullError as exc:
            return 507, str(exc)
        return None

    return UploadRule(UPLOADS, MAX_FILE_BYTES, refusal)


def reconstruction_router(service: JobService, errors: dict[int | str, dict[str, Any]]) -> APIRouter:
    router = APIRouter(tags=["reconstructions"], responses=errors)

    @router.get("/imports", dependencies=READING)
    def list_folders() -> list[dict[str, Any]]:
        return list_imports(service.data_dir)

    @router.put(
        "/imports/{folder}/{file:path}",
        status_code=status.HTTP_201_CREATED,
        dependencies=MUTATING,
        openapi_extra=BINARY_BODY,
    )
    async def upload(folder: Name, file: UploadName, request: Request, response: Response) -> dict[str, Any]:
        body = await request.body()
        limits = service.config.service
        stored = await run_in_threadpool(  # checks, writes, hashes, fsyncs
            store_file, service.data_dir, folder, file, body, limits.max_import_bytes, limits.max_image_pixels
        )
        response.headers["Location"] = f"/v1/imports/{folder}/{file}"
        return stored

    @router.delete("/imports/{folder}", status_code=status.HTTP_204_NO_CONTENT, dependencies=MUTATING)
    def delete_folder(folder: Name) -> Response:
        remove_folder(service.data_dir, folder)
        return Response(status_code=status.HTTP_204_NO_CONTENT)

    @router.post(
        "/reconstructions", status_code=status.HTTP_202_ACCEPTED, response_model=JobView, dependencies=MUTATING
    )
    def create_reconstruction(body: ReconstructionRequest, response: Response) -> JobView:
        job = service.submit_reconstruction(body.model_dump(exclude_none=True))
        response.headers["Location"] = f"/v1/scans/{job.id}"
        return JobView.of(job, "/v1/scans")

    return router
