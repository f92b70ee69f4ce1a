"""Moving a data directory whole: `slrig store migrate OLD NEW`. The shipped configs once kept
their data in `scans/`, so scans landed in `scans/scans/<id>`; they now use `slrig-data/`
(`slrig-data/scans/<id>`), and this moves an earlier store there. The store keeps no absolute
path (job records name their files relative to their folder), so a rename is the whole move. It is
refused while a daemon holds the old directory, onto anything that exists, or across file systems
(where a rename is not atomic: copy it, check it, then delete the old one yourself)."""

from __future__ import annotations

import errno
import os
from dataclasses import dataclass
from pathlib import Path

from rig.service.errors import MigrationError
from rig.service.jobs import DB_NAME
from rig.service.recovery import LOCK_NAME, lock_data_dir

MARKS = (DB_NAME, "scans", "calibrations", "calibration", "imports")  # what a data directory holds


@dataclass(frozen=True)
class Migration:
    source: Path
    target: Path
    scans: int
    calibrations: int


def migrate_data_dir(source: Path, target: Path) -> Migration:
    """Rename the data directory `source` to `target`; MigrationError, with nothing moved, when it
    is not a data directory, a daemon uses it, `target` exists, or they are on different file
    systems."""
    if not source.is_dir() or not any((source / mark).exists() for mark in MARKS):
        raise MigrationError(f"{source}: not a slrig data directory (it holds none of {', '.join(MARKS)})")
    if target.exists() or target.is_symlink():
        raise MigrationError(f"{target}: exists already; give a new directory")
    if target.resolve().is_relative_to(source.resolve()):
        raise MigrationError(f"{target}: inside {source}; give a directory beside it")
    counted = Migration(source, target, _count(source / "scans"), _count(source / "calibrations"))
    lock = lock_data_dir(source)  # ConfigError while a daemon serves it: nothing moved
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        os.rename(source, target)
    except OSError as exc:
        if exc.errno == errno.EXDEV:
            raise MigrationError(
                f"{target}: on another file system than {source}; copy it there, check it, then remove the old one"
            ) from None
        raise MigrationError(f"{source} -> {target}: {exc.strerror}") from None
    finally:
        lock.close()
    (target / LOCK_NAME).unlink(missing_ok=True)  # the lock file came along; the next daemon makes its own
    return counted


def _count(folder: Path) -> int:
    return sum(1 for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")) if folder.is_dir() else 0
