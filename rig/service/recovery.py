"""What a crash can leave in the data directory, and how start-up and deletion keep it whole.

A scan or a calibration is written to `<id>.partial` and renamed when complete: start-up removes
every `.partial`. A deletion renames the job's folder to a hidden `.<id>.<random>.deleting` first,
then deletes the record, then the folder: a crash at any point leaves a `.deleting` folder whose
job start-up finishes deleting (record too). A folder named like a job with no record (left by a
crash of an older slrig, which deleted the record first) is removed too.
"""

from __future__ import annotations

import fcntl
import logging
import re
import secrets
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

from rig.errors import ConfigError
from rig.service.errors import JobNotFoundError
from rig.service.imports import JOB_ID
from rig.service.jobs import JobStore

log = logging.getLogger(__name__)

LOCK_NAME = "slrig.lock"
DOOMED = re.compile(r"^\.(?P<id>[^.]+)\.[0-9a-f]+\.deleting$")


def lock_data_dir(data_dir: Path) -> TextIO:
    """One daemon per data directory (a second would mark the first one's jobs interrupted);
    ConfigError naming output.data_dir when another holds it. Closing the file releases it."""
    data_dir.mkdir(parents=True, exist_ok=True)
    lock_file = (data_dir / LOCK_NAME).open("a")
    try:
        fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock_file.close()
        raise ConfigError("output.data_dir", [f"output.data_dir: another slrig daemon is using {data_dir}"]) from None
    return lock_file


def delete_folder(folder: Path, delete_record: Callable[[], None]) -> None:
    """Delete a job: its folder out of sight, then its record, then the folder's contents. If the
    record cannot be deleted (a full disk) the folder is put back and the error propagates."""
    doomed = folder.with_name(f".{folder.name}.{secrets.token_hex(4)}.deleting")
    try:
        folder.rename(doomed)
    except FileNotFoundError:  # a job that wrote no folder (failed, cancelled, queued)
        doomed = None
    try:
        delete_record()
    except BaseException:
        if doomed is not None:
            doomed.rename(folder)
        raise
    if doomed is not None:
        shutil.rmtree(doomed, ignore_errors=True)


def clear_leftovers(store: JobStore, job_dirs: tuple[Path, ...]) -> list[str]:
    """At start-up: finish interrupted deletions, remove half-written scans and folders whose
    record is gone. Returns what was removed (for the log and the tests)."""
    removed = []
    for root in job_dirs:
        for path in sorted(root.iterdir()) if root.is_dir() else []:
            if not path.is_dir():
                continue
            doomed = DOOMED.match(path.name)
            if doomed:
                _forget(store, doomed["id"])
            elif not (path.name.endswith(".partial") or (JOB_ID.match(path.name) and not _known(store, path.name))):
                continue
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path.name)
    if removed:
        log.info("start-up removed what interrupted jobs and deletions left: %s", ", ".join(removed))
    return removed


def _known(store: JobStore, job_id: str) -> bool:
    try:
        store.get(job_id)
    except JobNotFoundError:
        return False
    return True


def _forget(store: JobStore, job_id: str) -> None:
    if _known(store, job_id):
        store.delete(job_id)  # the deletion a crash interrupted: finish it
