"""The recognition gallery: labelled descriptors in SQLite, beside the scan records.

Each entry keeps its label, the scan it came from and the descriptor's settings. A gallery holds
one set of settings: an entry made with others is refused (`add`), as is a probe made with
others (`check_settings`), so descriptors are never compared across settings. A file that is not
a gallery, or one from a newer slrig (`PRAGMA user_version`), is refused and never written.
"""

from __future__ import annotations

import json
import re
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.errors import GalleryEntryNotFoundError, GalleryError, GalleryFileError
from rig.recognition.descriptor import Descriptor, DescriptorSettings

GALLERY_NAME = "gallery.db"
VERSION = 1
LABEL = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
_SQLITE_MAGIC = b"SQLite format 3\x00"
_SCHEMA = f"""
CREATE TABLE IF NOT EXISTS entries (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    label TEXT NOT NULL,
    scan_id TEXT NOT NULL UNIQUE,
    settings TEXT NOT NULL,
    features BLOB NOT NULL,
    distances BLOB NOT NULL,
    reference TEXT NOT NULL,
    created REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS entries_label ON entries (label);
PRAGMA user_version = {VERSION};
"""
_COLUMNS = {"id", "label", "scan_id", "settings", "features", "distances", "reference", "created"}


@dataclass(frozen=True)
class Entry:
    id: int
    label: str
    scan_id: str
    settings: DescriptorSettings
    created: float

    def as_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "label": self.label,
            "scan_id": self.scan_id,
            "settings": self.settings.as_dict(),
            "created": self.created,
        }


class Gallery:
    """One gallery file; each change is committed before it returns. Not shared between threads
    without the caller's lock."""

    def __init__(self, path: Path, create: bool = False) -> None:
        self.path = path
        self._db = _connect(path) if create or path.exists() else None  # an absent gallery reads as empty

    def close(self) -> None:
        if self._db is not None:
            self._db.close()

    def __enter__(self) -> Gallery:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def settings(self) -> DescriptorSettings | None:
        """The settings every entry shares (None: the gallery is empty)."""
        if self._db is None:
            return None
        row = self._db.execute("SELECT settings FROM entries LIMIT 1").fetchone()
        return None if row is None else DescriptorSettings(**json.loads(row[0]))

    def check_settings(self, settings: DescriptorSettings) -> None:
        """Refuse settings other than the gallery's, naming each that differs."""
        own = self.settings()
        if own is not None and own != settings:
            differ = [
                f"{k} {v!r} (gallery: {own.as_dict()[k]!r})"
                for k, v in settings.as_dict().items()
                if own.as_dict()[k] != v
            ]
            raise GalleryError(
                "descriptor settings differ from the gallery's, so they cannot be compared: " + ", ".join(differ)
            )

    def add(self, label: str, scan_id: str, descriptor: Descriptor) -> Entry:
        return self.add_many([(label, scan_id, descriptor)])[0]

    def add_many(self, items: list[tuple[str, str, Descriptor]]) -> list[Entry]:
        """Add (label, scan id, descriptor) items in one transaction: all of them, or (GalleryError
        naming the first refused) none."""
        for label, _, descriptor in items:
            if not LABEL.fullmatch(label):
                raise GalleryError(
                    f"label {label!r}: not a plain name (1 to 64 letters, digits, '.', '_' or '-', "
                    "starting with a letter or digit)"
                )
            self.check_settings(descriptor.settings)
        if len({d.settings for _, _, d in items}) > 1:
            raise GalleryError("the descriptors to add were made with different settings: they cannot be compared")
        if self._db is None:
            self._db = _connect(self.path)
        added = []
        self._db.execute("BEGIN")
        try:
            for label, scan_id, descriptor in items:
                added.append(self._insert(label, scan_id, descriptor))
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        return added

    def _insert(self, label: str, scan_id: str, descriptor: Descriptor) -> Entry:
        assert self._db is not None
        created = time.time()
        try:
            cursor = self._db.execute(
                "INSERT INTO entries (label, scan_id, settings, features, distances, reference, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    label,
                    scan_id,
                    json.dumps(descriptor.settings.as_dict()),
                    descriptor.features.astype("<f8").tobytes(),
                    descriptor.distances.astype("<f8").tobytes(),
                    json.dumps(descriptor.reference.tolist()),
                    created,
                ),
            )
        except sqlite3.IntegrityError:
            held = self._db.execute("SELECT label FROM entries WHERE scan_id = ?", (scan_id,)).fetchone()
            raise GalleryError(f"scan {scan_id} is in the gallery already (label {held[0]!r})") from None
        return Entry(int(cursor.lastrowid or 0), label, scan_id, descriptor.settings, created)

    def entry(self, entry_id: int) -> Entry:
        row = (
            None
            if self._db is None
            else self._db.execute(
                "SELECT id, label, scan_id, settings, created FROM entries WHERE id = ?", (entry_id,)
            ).fetchone()
        )
        if row is None:
            raise GalleryEntryNotFoundError(f"no gallery entry {entry_id}")
        return _entry(row)

    def entries(self, label: str | None = None) -> list[Entry]:
        if self._db is None:
            return []
        query = "SELECT id, label, scan_id, settings, created FROM entries"
        rows = self._db.execute(
            query + (" WHERE label = ? ORDER BY id" if label else " ORDER BY id"), (label,) if label else ()
        )
        return [_entry(row) for row in rows]

    def remove(self, entry_id: int) -> Entry:
        entry = self.entry(entry_id)
        assert self._db is not None
        self._db.execute("DELETE FROM entries WHERE id = ?", (entry_id,))
        return entry

    def features(self) -> tuple[list[Entry], np.ndarray]:
        """Every entry and its features, one row each (an empty gallery: no rows)."""
        if self._db is None:
            return [], np.zeros((0, 0))
        rows = self._db.execute(
            "SELECT id, label, scan_id, settings, created, features FROM entries ORDER BY id"
        ).fetchall()
        if not rows:
            return [], np.zeros((0, 0))
        matrix = np.frombuffer(b"".join(row[5] for row in rows), "<f8").reshape(len(rows), -1)
        return [_entry(row[:5]) for row in rows], matrix

    def columns(self) -> tuple[np.ndarray, list[str], list[str], np.ndarray]:
        """Every entry's id, label and scan id, and its features one row each: what identification
        reads, without building an Entry per row (rig.recognition.matrix)."""
        if self._db is None:
            return np.zeros(0, np.int64), [], [], np.zeros((0, 0))
        rows = self._db.execute("SELECT id, label, scan_id, features FROM entries ORDER BY id").fetchall()
        if not rows:
            return np.zeros(0, np.int64), [], [], np.zeros((0, 0))
        ids, labels, scan_ids, blobs = zip(*rows, strict=True)
        features = np.frombuffer(b"".join(blobs), "<f8").reshape(len(rows), -1)
        return np.asarray(ids, np.int64), list(labels), list(scan_ids), features

    def scan_ids(self) -> set[str]:
        """The scans the gallery holds (an entry each)."""
        if self._db is None:
            return set()
        return {row[0] for row in self._db.execute("SELECT scan_id FROM entries")}

    def signature(self) -> tuple[object, ...]:
        """What changes whenever an entry is added or removed (the count, the newest id, the newest time)."""
        if self._db is None:
            return (0, None, None)
        return tuple(self._db.execute("SELECT count(*), max(id), max(created) FROM entries").fetchone())


def _connect(path: Path) -> sqlite3.Connection:
    """The gallery at `path`, created if absent; refused (GalleryError, the file untouched) if it is
    not a gallery or is a newer one."""
    exists = path.exists()
    if exists:
        _check_file(path)
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
    db = sqlite3.connect(str(path), isolation_level=None, timeout=10.0, check_same_thread=False)
    try:
        db.execute("PRAGMA synchronous=FULL")
        if exists:
            _check_schema(db, path)
        else:
            db.executescript(_SCHEMA)
    except sqlite3.DatabaseError as exc:
        db.close()
        raise GalleryFileError(f"{path}: not a gallery ({exc}); it is left as it is") from None
    except GalleryFileError:
        db.close()
        raise
    return db


def _entry(row: tuple) -> Entry:
    return Entry(int(row[0]), row[1], row[2], DescriptorSettings(**json.loads(row[3])), float(row[4]))


def _check_file(path: Path) -> None:
    try:
        with path.open("rb") as f:
            head = f.read(len(_SQLITE_MAGIC))
    except OSError as exc:
        raise GalleryFileError(f"{path}: cannot read the gallery ({exc.strerror})") from None
    if head != _SQLITE_MAGIC:
        raise GalleryFileError(f"{path}: not a gallery (not an SQLite database); it is left as it is")


def _check_schema(db: sqlite3.Connection, path: Path) -> None:
    version = db.execute("PRAGMA user_version").fetchone()[0]
    if version > VERSION:
        raise GalleryFileError(f"{path}: a gallery from a newer slrig (version {version}; this one reads {VERSION})")
    columns = {row[1] for row in db.execute("PRAGMA table_info(entries)")}
    if version != VERSION or columns != _COLUMNS:
        raise GalleryFileError(f"{path}: not a gallery (no entries table of version {VERSION}); it is left as it is")
