"""Job records in SQLite (WAL, synchronous=FULL): what was asked, where it is, how it ended.

States: queued -> running -> done | failed | cancelled | interrupted; a queued job can also be
cancelled or interrupted without running. Terminal states never change. A daemon that starts
marks every job it finds queued or running as interrupted: hardware is never re-run by itself.
"""

from __future__ import annotations

import enum
import json
import logging
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.service.errors import IllegalTransitionError, JobNotFoundError

log = logging.getLogger(__name__)


class JobState(enum.StrEnum):
    """Where a job is; shared by the service, its store and the API."""

    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"


class JobKind(enum.StrEnum):
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


@dataclass(frozen=True)
class Job:
    id: str
    kind: JobKind
    state: JobState | None  # None: a placeholder for a record that is gone
    request: dict[str, Any]
    created: float
    started: float | None
    finished: float | None
    stage: str | None
    fraction: float
    error: str | None
    result: dict[str, Any] | None

    @property
    def terminal(self) -> bool:
        return self.state in TERMINAL

    @classmethod
    def placeholder(cls, job_id: str, kind: JobKind) -> Job:
        """A record's identity only (for a job whose record is gone)."""
        return cls(job_id, kind, None, {}, 0.0, None, None, None, 0.0, None, None)


class JobStore:
    """Thread-safe access to the jobs table; each change is committed before it returns."""

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(str(path), check_same_thread=False, isolation_level=None, timeout=10.0)
        self._db.row_factory = sqlite3.Row
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")  # a commit survives power loss
        self._db.executescript(_SCHEMA)

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def integrity_ok(self) -> bool:
        with self._lock:
            return self._db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"

    def add(self, job_id: str, kind: JobKind, request: dict[str, Any]) -> Job:
        with self._lock:
            self._db.execute(
                "INSERT INTO jobs (id, kind, state, request, created) VALUES (?, ?, 'queued', ?, ?)",
                (job_id, kind, json.dumps(request), time.time()),
            )
        log.info("%s %s: queued", kind, job_id)
        return self.get(job_id)

    def get(self, job_id: str) -> Job:
        with self._lock:
            row = self._db.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
        if row is None:
            raise JobNotFoundError(f"no job {job_id}")
        return _job(row)

    def transition(self, job_id: str, state: JobState, **fields: Any) -> Job:
        """Move a job to `state`, setting `error`, `result`, `stage` or `fraction` too."""
        now = time.time()
        with self._lock:
            row = self._db.execute("SELECT kind, state FROM jobs WHERE id = ?", (job_id,)).fetchone()
            if row is None:
                raise JobNotFoundError(f"no job {job_id}")
            if state not in TRANSITIONS.get(JobState(row["state"]), frozenset()):
                raise IllegalTransitionError(f"job {job_id}: {row['state']} -> {state} is not allowed")
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
            assignments = ", ".join(f"{key} = ?" for key in updates)
            self._db.execute(f"UPDATE jobs SET {assignments} WHERE id = ?", (*updates.values(), job_id))
        detail = f" ({fields['error']})" if fields.get("error") else ""
        log.info("%s %s: %s -> %s%s", row["kind"], job_id, row["state"], state, detail)
        return self.get(job_id)

    def progress(self, job_id: str, stage: str, fraction: float) -> None:
        with self._lock:
            self._db.execute(
                "UPDATE jobs SET stage = ?, fraction = ? WHERE id = ? AND state = 'running'", (stage, fraction, job_id)
            )

    def delete(self, job_id: str) -> None:
        with self._lock:
            self._db.execute("DELETE FROM jobs WHERE id = ?", (job_id,))
        log.info("job %s: deleted", job_id)

    def list(self, kind: JobKind, state: JobState | None, limit: int, offset: int) -> tuple[list[Job], int]:
        """Newest first; also the total matching, for paging."""
        where, args = "kind = ?", [kind]
        if state is not None:
            where += " AND state = ?"
            args.append(state)
        with self._lock:
            total = self._db.execute(f"SELECT COUNT(*) FROM jobs WHERE {where}", args).fetchone()[0]
            rows = self._db.execute(
                f"SELECT * FROM jobs WHERE {where} ORDER BY created DESC, id DESC LIMIT ? OFFSET ?",
                (*args, limit, offset),
            ).fetchall()
        return [_job(r) for r in rows], int(total)

    def interrupt_unfinished(self, reason: str) -> list[str]:
        """Mark every queued or running job interrupted, in one statement (at start-up and
        shutdown, when a worker may finish a job at the same moment); returns their ids."""
        with self._lock:
            rows = self._db.execute(
                "UPDATE jobs SET state = 'interrupted', error = ?, finished = ? "
                "WHERE state IN ('queued', 'running') RETURNING id, kind",
                (reason, time.time()),
            ).fetchall()
        for row in rows:
            log.info("%s %s: -> interrupted (%s)", row["kind"], row["id"], reason)
        return [row["id"] for row in rows]


def _job(row: sqlite3.Row) -> Job:
    return Job(
        id=row["id"],
        kind=JobKind(row["kind"]),
        state=JobState(row["state"]),
        request=json.loads(row["request"]),
        created=row["created"],
        started=row["started"],
        finished=row["finished"],
        stage=row["stage"],
        fraction=row["fraction"],
        error=row["error"],
        result=json.loads(row["result"]) if row["result"] else None,
    )
