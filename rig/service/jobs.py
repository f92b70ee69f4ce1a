"""Job records in SQLite (WAL, synchronous=FULL): what was asked, where it is, how it ended.

States: queued -> running -> done | failed | cancelled | interrupted; a queued job can also be
cancelled or interrupted without running. Terminal states never change. A daemon that starts
marks every job it finds queued or running as interrupted: hardware is never re-run by itself.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import enum
import json
import logging
import re
import sqlite3
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.service.errors import IllegalTransitionError, JobNotFoundError, StorageFullError
from rig.store import json_problem

log = logging.getLogger(__name__)


DB_NAME = "slrig.db"  # in output.data_dir


class JobState(enum.StrEnum):
    """Where a job is; shared by the service, its store and the API."""

    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"


class JobType(enum.StrEnum):
    SCAN = "scan"
    CALIBRATION = "calibration"


TERMINAL = frozenset({JobState.DONE, JobState.FAILED, JobState.CANCELLED, JobState.INTERRUPTED})
TRANSITIONS = {
    JobState.QUEUED: frozenset({JobState.RUNNING, JobState.CANCELLED, JobState.INTERRUPTED}),
    JobState.RUNNING: frozenset({JobState.DONE, JobState.FAILED, JobState.CANCELLED, JobState.INTERRUPTED}),
}

_SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    id TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    state TEXT NOT NULL,
    request TEXT NOT NULL,
    created REAL NOT NULL,
    started REAL,
    finished REAL,
    stage TEXT,
    fraction REAL NOT NULL DEFAULT 0,
    error TEXT,
    result TEXT
);
CREATE INDEX IF NOT EXISTS jobs_kind_created ON jobs (kind, created);
"""


# A listing's rows: a record of a kind this version does not know is listed with the scans (as a
# damaged record, so that it can be seen and deleted).
_KIND_MATCH = {JobType.SCAN: "kind != 'calibration'", JobType.CALIBRATION: "kind = 'calibration'"}
JOB_ID = re.compile(r"^[0-9]{8}-[0-9]{6}-[0-9a-f]{6}$")

# SQLite's primary result codes for a database that cannot take a write now: busy, locked,
# read-only, an I/O error, corrupt, full, cannot be opened, not a database.
UNWRITABLE = frozenset({5, 6, 8, 10, 11, 13, 14, 26})


@dataclass(frozen=True)
class Job:
    id: str
    kind: JobType
    state: JobState | None  # None: a placeholder for a record that is gone, or a state unreadable (see problem)
    request: dict[str, Any]
    created: float
    started: float | None
    finished: float | None
    stage: str | None
    fraction: float
    error: str | None
    result: dict[str, Any] | None
    problem: str | None = None  # why the record cannot be served as stored (then shown without that part)

    @property
    def terminal(self) -> bool:
        return self.state in TERMINAL

    @classmethod
    def placeholder(cls, job_id: str, kind: JobType) -> Job:
        """A record's identity only (for a job whose record is gone)."""
        return cls(job_id, kind, None, {}, 0.0, None, None, None, 0.0, None, None)


class JobStore:
    """Thread-safe access to the jobs table; each change is committed before it returns.

    When the database cannot be written (a full disk, an I/O error) a job's state changes are
    kept in memory, shown by every read, and written by `flush()` once the disk takes them again;
    `unsaved` says why meanwhile. New records and deletions are refused instead (StorageFullError).
    """

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None, timeout=10.0)
        self._db.row_factory = sqlite3.Row
        self._db.text_factory = text_of  # a hand edit's invalid UTF-8 is a named problem, not an error
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")  # a commit survives power loss
        self._db.executescript(_SCHEMA)
        self._pending: dict[str, dict[str, Any]] = {}  # job id -> column values not yet written
        self._write_error: str | None = None

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def integrity_ok(self) -> bool:
        with self._lock:
            return self._db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"

    @property
    def unsaved(self) -> str | None:
        """Why job states are held in memory only (None when everything is written)."""
        with self._lock:
            return self._write_error if self._pending else None

    def _write(self, sql: str, args: tuple[Any, ...]) -> list[sqlite3.Row]:
        """One statement under the lock held by the caller; StorageFullError if the disk or the
        file refuses it (other errors are the program's, and propagate)."""
        try:
            return self._db.execute(sql, args).fetchall()
        except sqlite3.DatabaseError as exc:
            if (getattr(exc, "sqlite_errorcode", 0) & 0xFF) not in UNWRITABLE:
                raise
            self._write_error = f"the job database cannot be written: {exc}"
            raise StorageFullError(self._write_error) from exc

    def add(self, job_id: str, kind: JobType, request: dict[str, Any]) -> Job:
        with self._lock:
            self._write(
                "INSERT INTO jobs (id, kind, state, request, created) VALUES (?, ?, 'queued', ?, ?)",
                (job_id, kind, json.dumps(request), time.time()),
            )
        log.info("%s %s: queued", kind, job_id)
        return self.get(job_id)

    def get(self, job_id: str) -> Job:
        with self._lock:
            row = self._db.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
            pending = dict(self._pending.get(job_id, {}))
        if row is None:
            raise JobNotFoundError(f"no job {job_id}")
        return job_from_row(row, pending)

    def transition(self, job_id: str, state: JobState, **fields: Any) -> Job:
        """Move a job to `state`, setting `error`, `result`, `stage` or `fraction` too; held in
        memory when the database cannot be written. JobNotFoundError for no such job,
        IllegalTransitionError for a move the state machine does not allow (or from a state
        this version does not know)."""
        now = time.time()
        with self._lock:
            row = self._db.execute("SELECT kind, state FROM jobs WHERE id = ?", (job_id,)).fetchone()
            if row is None:
                raise JobNotFoundError(f"no job {job_id}")
            stored = self._pending.get(job_id, {}).get("state", row["state"])
            if stored not in set(JobState):
                raise IllegalTransitionError(f"job {job_id}: its stored state {stored!r} is not one this version knows")
            current = JobState(stored)
            if state not in TRANSITIONS.get(current, frozenset()):
                raise IllegalTransitionError(f"job {job_id}: {current} -> {state} is not allowed")
            updates: dict[str, Any] = {"state": state}
            if state is JobState.RUNNING:
                updates["started"] = now
            if state in TERMINAL:
                updates["finished"] = now
            for key in ("error", "stage", "fraction"):
                if key in fields:
                    updates[key] = fields[key]
            if "result" in fields:
                updates["result"] = json.dumps(fields["result"], allow_nan=False)
            self._update(job_id, updates)
        detail = f" ({fields['error']})" if fields.get("error") else ""
        log.info("%s %s: %s -> %s%s", row["kind"], job_id, current, state, detail)
        return self.get(job_id)

    def _update(self, job_id: str, updates: dict[str, Any], others: bool = True) -> None:
        """Write a job's changed columns (with any held before them), else hold them in memory;
        a write that succeeds writes what other jobs held too (`others`)."""
        merged = {**self._pending.get(job_id, {}), **updates}
        if not merged:
            return
        assignments = ", ".join(f"{key} = ?" for key in merged)
        try:
            self._write(f"UPDATE jobs SET {assignments} WHERE id = ?", (*merged.values(), job_id))
        except StorageFullError:
            if job_id not in self._pending:
                log.error("job %s: %s; its state is kept in memory until it can be written", job_id, self._write_error)
            self._pending[job_id] = merged
            return
        self._pending.pop(job_id, None)
        if self._pending and others:
            self._flush_held()

    def _flush_held(self) -> bool:
        for job_id in list(self._pending):
            self._update(job_id, {}, others=False)
            if job_id in self._pending:
                return False
        if self._write_error is not None:
            log.info("the job database is written again")
            self._write_error = None
        return True

    def flush(self) -> bool:
        """Write the states held in memory; True when nothing is held any more."""
        with self._lock:
            return self._flush_held()

    def progress(self, job_id: str, stage: str, fraction: float) -> None:
        with self._lock:
            if job_id in self._pending:  # the state is held in memory: the progress with it
                self._pending[job_id].update(stage=stage, fraction=fraction)
                return
            with contextlib.suppress(StorageFullError):  # progress is not worth failing a job for
                self._write(
                    "UPDATE jobs SET stage = ?, fraction = ? WHERE id = ? AND state = 'running'",
                    (stage, fraction, job_id),
                )

    def delete(self, job_id: str) -> None:
        """StorageFullError when it cannot be written; the record is then unchanged."""
        with self._lock:
            self._write("DELETE FROM jobs WHERE id = ?", (job_id,))
            self._pending.pop(job_id, None)
        log.info("job %s: deleted", job_id)

    def list(self, kind: JobType, state: JobState | None, limit: int, offset: int) -> tuple[list[Job], int]:
        """Newest first; also the total matching, for paging. States held in memory count."""
        with self._lock:
            pending = {job_id: dict(values) for job_id, values in self._pending.items()}
            if pending and state is not None:  # filter on the held state, not the table's
                rows = self._db.execute(
                    f"SELECT * FROM jobs WHERE {_KIND_MATCH[kind]} ORDER BY created DESC, id DESC"
                ).fetchall()
            else:
                where, args = (f"{_KIND_MATCH[kind]} AND state = ?", [state]) if state else (_KIND_MATCH[kind], [])
                total = self._db.execute(f"SELECT COUNT(*) FROM jobs WHERE {where}", args).fetchone()[0]
                rows = self._db.execute(
                    f"SELECT * FROM jobs WHERE {where} ORDER BY created DESC, id DESC LIMIT ? OFFSET ?",
                    (*args, limit, offset),
                ).fetchall()
                return [job_from_row(r, pending.get(r["id"], {})) for r in rows], int(total)
        jobs = [job for r in rows if (job := job_from_row(r, pending.get(r["id"], {}))).state is state]
        return jobs[offset : offset + limit], len(jobs)

    def interrupt_unfinished(self, reason: str) -> list[str]:
        """Mark every queued or running job interrupted (at start-up and shutdown, when a worker
        may finish a job at the same moment), judged by its state held in memory where there is
        one; held in memory too when the database cannot take it. Returns their ids."""
        now, interrupted = time.time(), []
        with self._lock:
            rows = self._db.execute("SELECT id, kind, state FROM jobs WHERE state IN ('queued', 'running')").fetchall()
            unfinished = {row["id"]: row["kind"] for row in rows}
            for job_id, values in self._pending.items():
                if values.get("state") in TERMINAL:
                    unfinished.pop(job_id, None)  # ended: its held state is written below or later
                elif "state" in values:
                    unfinished.setdefault(job_id, "job")
            for job_id in unfinished:
                self._update(job_id, {"state": JobState.INTERRUPTED, "error": reason, "finished": now}, others=False)
                interrupted.append(job_id)
            self._flush_held()
        for job_id in interrupted:
            log.info("%s %s: -> interrupted (%s)", unfinished[job_id], job_id, reason)
        return interrupted


def text_of(raw: bytes) -> str:
    """A TEXT column as Python reads it: bytes that are not UTF-8 kept as lone surrogates, which
    `json_problem` then names, so one bad byte never makes the table unreadable."""
    return raw.decode("utf-8", "surrogateescape")


def job_from_row(row: sqlite3.Row, pending: dict[str, Any]) -> Job:
    """A record as it can be served: a column that cannot (unreadable JSON, a value JSON cannot
    carry back, a state or kind this version does not know) is left out and named in `problem`,
    so one bad record (an older version's, a bug's, a hand edit's) never breaks a listing."""
    values = {**dict(row), **pending}
    problems: list[str] = []

    def column(name: str, decode: Callable[[Any], Any], fallback: Any) -> Any:
        try:
            decoded = decode(values[name])
        except (ValueError, TypeError, RecursionError) as exc:
            problems.append(f"{name}: {exc}")
            return fallback
        found = json_problem(decoded, name)
        if found:
            problems.append(found)
            return fallback
        return decoded

    def number(value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TypeError(f"{value!r} is not a number")
        return float(value)

    def moment(value: Any) -> float:
        seconds = number(value)
        try:
            dt.datetime.fromtimestamp(seconds, dt.UTC)
        except (OverflowError, OSError):
            raise ValueError(f"{value!r} is not a time") from None
        return seconds

    def optional(decode: Callable[[Any], Any]) -> Callable[[Any], Any]:
        return lambda value: None if value is None else decode(value)

    def record(text: Any) -> Any:
        decoded = json.loads(text)
        if not isinstance(decoded, dict):
            raise TypeError(f"not a JSON object but a {type(decoded).__name__}")
        return decoded

    job_id = str(values["id"])
    if not JOB_ID.match(job_id):
        problems.append(f"id: {job_id!r} is not a job id the API serves; `slrig store check --repair` quarantines it")
    return Job(
        id=job_id if json_problem(job_id) is None else repr(job_id),
        kind=column("kind", JobType, JobType.SCAN),
        state=column("state", JobState, None),
        request=column("request", record, {}),
        created=column("created", moment, 0.0),
        started=column("started", optional(moment), None),
        finished=column("finished", optional(moment), None),
        stage=column("stage", optional(str), None),
        fraction=column("fraction", number, 0.0),
        error=column("error", optional(str), None),
        result=column("result", lambda text: record(text) if text else None, None),
        problem="; ".join(problems) or None,
    )
