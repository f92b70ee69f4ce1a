"""`slrig store check [--repair]`: the job database checked offline.

Every record is read as the daemon serves it (rig.service.jobs.job_from_row); a record with a part
that cannot be served (an older version's value, a bug's, a hand edit's) is reported, and with
`repair` moved into the `quarantine` table of the same database (kept, with its problem, for a
person to look at) and out of the job listing. The scan or calibration folder of a quarantined job
stays where it is. Repair takes the data directory's lock, so it never runs beside a daemon.
"""

from __future__ import annotations

import contextlib
import sqlite3
import time
from dataclasses import dataclass, field
from pathlib import Path

from rig.errors import ConfigError
from rig.service.jobs import DB_NAME, job_from_row, text_of
from rig.service.recovery import lock_data_dir

_QUARANTINE = """
CREATE TABLE IF NOT EXISTS quarantine (
    id TEXT, kind TEXT, state TEXT, request TEXT, created REAL, started REAL, finished REAL,
    stage TEXT, fraction REAL, error TEXT, result TEXT, problem TEXT NOT NULL, quarantined REAL NOT NULL
)
"""
_COLUMNS = "id, kind, state, request, created, started, finished, stage, fraction, error, result"


@dataclass
class StoreReport:
    database: Path
    records: int = 0
    integrity: str = "ok"
    damaged: list[dict[str, str]] = field(default_factory=list)  # id and problem of each
    quarantined: int = 0

    @property
    def clean(self) -> bool:
        """Nothing left to repair (a repair that quarantined every damaged record counts)."""
        return self.integrity == "ok" and self.quarantined == len(self.damaged)

    def as_dict(self) -> dict[str, object]:
        return {
            "database": str(self.database),
            "records": self.records,
            "integrity": self.integrity,
            "damaged": self.damaged,
            "quarantined": self.quarantined,
            "clean": self.clean,
        }


def check_store(data_dir: Path, repair: bool = False) -> StoreReport:
    """The report of `data_dir`'s job database; ConfigError naming output.data_dir when there is
    none, or (with `repair`) when a daemon holds the directory."""
    database = data_dir / DB_NAME
    if not database.is_file():
        raise ConfigError("output.data_dir", [f"output.data_dir: {data_dir} holds no job database ({DB_NAME})"])
    lock = lock_data_dir(data_dir) if repair else None
    report = StoreReport(database)
    try:
        db = sqlite3.connect(str(database), isolation_level=None, timeout=10.0)
        db.row_factory = sqlite3.Row
        db.text_factory = text_of
        with contextlib.closing(db):
            report.integrity = str(db.execute("PRAGMA integrity_check").fetchone()[0])
            rows = db.execute(f"SELECT {_COLUMNS}, rowid FROM jobs").fetchall()
            report.records = len(rows)
            damaged = []
            for row in rows:
                job = job_from_row(row, {})
                if job.problem:
                    report.damaged.append({"id": job.id, "problem": job.problem})
                    damaged.append(row["rowid"])
            if repair and damaged:
                report.quarantined = _quarantine(db, damaged, report.damaged)
    except sqlite3.DatabaseError as exc:  # not a database, or one SQLite cannot read at all
        raise ConfigError("output.data_dir", [f"output.data_dir: {database} cannot be read: {exc}"]) from None
    finally:
        if lock is not None:
            lock.close()
    return report


def _quarantine(db: sqlite3.Connection, rowids: list[int], damaged: list[dict[str, str]]) -> int:
    """Move the records into `quarantine` in one transaction: each is in one table or the other."""
    now = time.time()
    db.execute(_QUARANTINE)
    db.execute("BEGIN IMMEDIATE")
    try:
        for rowid, found in zip(rowids, damaged, strict=True):
            db.execute(
                f"INSERT INTO quarantine ({_COLUMNS}, problem, quarantined) "
                f"SELECT {_COLUMNS}, ?, ? FROM jobs WHERE rowid = ?",
                (found["problem"], now, rowid),
            )
            db.execute("DELETE FROM jobs WHERE rowid = ?", (rowid,))
        db.execute("COMMIT")
    except BaseException:
        db.execute("ROLLBACK")
        raise
    return len(rowids)
