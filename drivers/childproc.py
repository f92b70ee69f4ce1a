"""A supervised worker process spoken to over pipes, with a deadline on every write and answer.

Device code that can crash or hang its process (DepthAI's native aborts, a display server) runs in
a worker; a dead or silent worker fails the operation with a DeviceError, not the daemon. After a
timeout the exchange is out of step (a late answer may still come), so callers abandon the worker.
"""

from __future__ import annotations

import contextlib
import os
import select
import subprocess
import sys
import tempfile
import time

from drivers.errors import DeviceDisconnectedError, DeviceTimeoutError


class WorkerProcess:
    def __init__(self, name: str, module: str, args: list[str], env: dict[str, str] | None = None) -> None:
        self.name = name
        # A file, not a pipe: the worker's logging can never block it. Closed in stop().
        self._stderr = tempfile.TemporaryFile()  # noqa: SIM115
        self._process = subprocess.Popen(
            [sys.executable, "-m", module, *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            env={**os.environ, **(env or {})},
        )
        assert self._process.stdin is not None
        os.set_blocking(self._process.stdin.fileno(), False)
        self._buffer = bytearray()  # read from the pipe unbuffered (os.read), kept here

    @property
    def pid(self) -> int:
        return self._process.pid

    @property
    def alive(self) -> bool:
        return self._process.poll() is None

    def _gone(self, what: str) -> DeviceDisconnectedError:
        return DeviceDisconnectedError(
            f"{self.name}: the worker process {what} (exit code {self._process.poll()}){self._last_error()}"
        )

    def send(self, data: bytes, timeout_s: float = 5.0) -> None:
        """Write `data`, all of it before the deadline, or fail (a worker that stops reading)."""
        stdin = self._process.stdin
        if not self.alive or stdin is None:
            raise self._gone("is not running")
        fd, view, deadline = stdin.fileno(), memoryview(data), time.monotonic() + timeout_s
        while view:
            _, writable, _ = select.select([], [fd], [], max(0.0, deadline - time.monotonic()))
            if not writable:
                raise DeviceTimeoutError(f"{self.name}: the worker took no input within {timeout_s:g} s")
            try:
                view = view[os.write(fd, view) :]
            except BlockingIOError:
                continue
            except (BrokenPipeError, OSError) as exc:
                raise self._gone(f"is gone ({exc})") from exc

    def _fill(self, deadline: float) -> None:
        """Read what the worker has written so far into the buffer, waiting until `deadline`."""
        assert self._process.stdout is not None
        fd = self._process.stdout.fileno()
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            if not self.alive:  # under load its exit can show before the closed pipe does
                raise self._gone("exited without answering")
            raise DeviceTimeoutError(f"{self.name}: no answer from the worker in time")
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(timeout=1)
            raise self._gone("exited")
        self._buffer += chunk

    def read_line(self, timeout_s: float) -> bytes:
        deadline = time.monotonic() + timeout_s
        while b"\n" not in self._buffer:
            self._fill(deadline)
        line, _, rest = bytes(self._buffer).partition(b"\n")
        self._buffer = bytearray(rest)
        return line + b"\n"

    def read_exact(self, size: int, timeout_s: float) -> bytes:
        deadline = time.monotonic() + timeout_s
        while len(self._buffer) < size:
            self._fill(deadline)
        data = bytes(self._buffer[:size])
        del self._buffer[:size]
        return data

    def _last_error(self) -> str:
        if self.alive:
            return ""
        try:
            self._stderr.seek(0)
            lines = self._stderr.read().decode(errors="replace").strip().splitlines()
        except (OSError, ValueError):
            return ""
        return f": {lines[-1]}" if lines else ""

    def stop(self, goodbye: bytes | None, timeout_s: float) -> str:
        """Say `goodbye` (if alive), wait, kill if it lingers; returns its last error line."""
        process = self._process
        if goodbye is not None and self.alive:
            with contextlib.suppress(DeviceTimeoutError, DeviceDisconnectedError):
                self.send(goodbye, timeout_s)
        try:
            process.wait(timeout=timeout_s if goodbye is not None else 0.05)
        except subprocess.TimeoutExpired:
            process.kill()
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(timeout=timeout_s)
        error = self._last_error()
        for stream in (process.stdin, process.stdout, self._stderr):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()
        return error.removeprefix(": ")


class WorkerDevice:
    """What a device run in a worker process shares (mixed in before Projector or Camera): its
    resolution, and the worker's pid for tests and diagnostics."""

    _resolution: tuple[int, int]
    _worker: WorkerProcess | None

    @property
    def resolution(self) -> tuple[int, int]:
        return self._resolution

    @property
    def worker_pid(self) -> int | None:
        return None if self._worker is None else self._worker.pid
