"""Durable writes: temp file in the same directory, fsync, rename, fsync the directory."""

from __future__ import annotations

import contextlib
import contextvars
import ctypes
import errno
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

# Who may let a folder appear, in this thread: the job service's worker publishes through its gate,
# which refuses once the daemon is stopping (the job is then recorded interrupted, and no finished
# folder may appear behind that record). Elsewhere (the CLI) folders are published directly.
PublishGate = Callable[[Callable[[], None]], None]
_gate: contextvars.ContextVar[PublishGate | None] = contextvars.ContextVar("publish_gate", default=None)


@contextlib.contextmanager
def publishing_through(gate: PublishGate) -> Iterator[None]:
    """Within this block (in this thread), publish_folder renames through `gate(rename)`, which
    either calls `rename` or raises to refuse."""
    token = _gate.set(gate)
    try:
        yield
    finally:
        _gate.reset(token)


def fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _read_umask() -> int:
    # os.umask can only be read by setting it; do that once, at import, before any threads exist.
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _read_umask()


def write_atomic(path: str | Path, data: bytes | Iterable[bytes]) -> None:
    """Replace `path` with `data` (or its pieces, written in turn) so that a crash leaves either the
    old or the new file whole."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)  # mkstemp creates 0600; give the usual file mode
        with os.fdopen(fd, "wb") as f:
            for piece in [data] if isinstance(data, bytes) else data:
                f.write(piece)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    fsync_dir(path.parent)


_RENAME_NOREPLACE = 1
_AT_FDCWD = -100


def rename_no_replace(src: Path, dst: Path) -> None:
    """Rename `src` to `dst`, failing with FileExistsError if `dst` exists, atomically where the
    kernel offers renameat2(RENAME_NOREPLACE) (Linux); plain os.rename would silently replace an
    empty directory that appeared at `dst` after a check."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        renameat2 = None
    if renameat2 is not None:
        result = renameat2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), _RENAME_NOREPLACE)
        if result == 0:
            return
        err = ctypes.get_errno()
        if err == errno.EEXIST:
            raise FileExistsError(errno.EEXIST, "already exists", str(dst))
        if err not in (errno.ENOSYS, errno.EINVAL):  # other failures are real; those two mean unsupported
            raise OSError(err, os.strerror(err), str(src))
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, "already exists", str(dst))
    os.rename(src, dst)


def publish_folder(partial: Path, target: Path) -> None:
    """Make a completely written folder visible under its final name, durably; FileExistsError
    rather than replace one that is there, and whatever a gate (publishing_through) raises to
    refuse it (then `partial` is removed)."""
    fsync_dir(partial)
    gate = _gate.get()
    if gate is None:
        rename_no_replace(partial, target)
    else:
        asked = False

        def rename() -> None:
            nonlocal asked
            asked = True
            rename_no_replace(partial, target)

        try:
            gate(rename)
        except BaseException:
            if not asked:  # refused: what was written will never be published
                shutil.rmtree(partial, ignore_errors=True)
            raise
    fsync_dir(target.parent)
