"""What a crash can leave in the data directory, and how start-up and deletion keep it whole.

A scan or a calibration is written to `<id>.partial` and renamed when complete: start-up removes
every `.partial`. A deletion renames the job's folder to a hidden `.<id>.<random>.deleting` first,
then deletes the record, then the folder: a crash at any point leaves a `.deleting` folder whose
job start-up finishes deleting (record too).
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
from rig.service.errors import JobNotFoundError, StorageFullError
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


def hide_folder(folder: Path, delete_record: Callable[[], None]) -> Path | None:
    """The first half of deleting a job: its folder out of sight, then its record. Returns the
    hidden folder for `discard` (None when the job wrote none). If the record cannot be deleted (a
    full disk) the folder is put back and the error propagates: nothing changed."""
    doomed: Path | None = folder.with_name(f".{folder.name}.{secrets.token_hex(4)}.deleting")
    try:
        folder.rename(doomed)  # type: ignore[arg-type]
    except FileNotFoundError:  # a job that wrote no folder (failed, cancelled, queued)
        doomed = None
    try:
        delete_record()
    except BaseException:
        if doomed is not None:
            doomed.rename(folder)
        raise
    return doomed


def discard(doomed: Path | None) -> None:
    """The second half: the hidden folder's contents (a crash here is finished at start-up)."""
    if doomed is not None:
        shutil.rmtree(doomed, ignore_errors=True)


def clear_leftovers(store: JobStore, job_dirs: tuple[Path, ...]) -> list[str]:
    """At start-up, before anything is written: remove half-written folders (`.partial`, which
    frees a disk a crash left full), then finish interrupted deletions (`.deleting`: the record
    too, unless the database cannot be written now; then the next start finishes it). A folder
    without a record is left alone: `slrig scan` writes there too. Returns what was removed."""
    removed = []
    folders = [p for root in job_dirs if root.is_dir() for p in sorted(root.iterdir()) if p.is_dir()]
    for path in folders:
        if path.name.endswith(".partial"):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path.name)
    for path in folders:
        doomed = DOOMED.match(path.name)
        if doomed is None:
            continue
        try:
            _forget(store, doomed["id"])
        except StorageFullError as exc:
            log.error("%s left for the next start: %s", path.name, exc)
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path.name)
    if removed:
        log.info("start-up removed what interrupted jobs and deletions left: %s", ", ".join(removed))
    return removed


def _forget(store: JobStore, job_id: str) -> None:
    try:
        store.get(job_id)
    except JobNotFoundError:
        return
    store.delete(job_id)  # the deletion a crash interrupted: finish it
