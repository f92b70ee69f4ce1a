"""A supervised worker process spoken to over pipes, with a deadline on every answer.

Device code that can crash or hang its process (DepthAI's native aborts, a display server) runs in
a worker; a dead or silent worker fails the operation with a DeviceError, not the daemon.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time

from drivers.errors import DeviceDisconnectedError, DeviceTimeoutError


class WorkerProcess:
    def __init__(self, name: str, module: str, args: list[str], env: dict[str, str] | None = None) -> None:
        self.name = name
        self._process = subprocess.Popen(
            [sys.executable, "-m", module, *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env={**os.environ, **(env or {})},
        )
        self._buffer = bytearray()  # read from the pipe unbuffered (os.read), kept here

    @property
    def pid(self) -> int:
        return self._process.pid

    @property
    def alive(self) -> bool:
        return self._process.poll() is None

    def send(self, data: bytes) -> None:
        stdin = self._process.stdin
        if not self.alive or stdin is None:
            raise DeviceDisconnectedError(
                f"{self.name}: the worker process is not running (exit code {self._process.poll()})"
            )
        try:
            stdin.write(data)
            stdin.flush()
        except (BrokenPipeError, OSError) as exc:
            raise DeviceDisconnectedError(f"{self.name}: the worker process is gone ({exc})") from exc

    def _fill(self, deadline: float) -> None:
        """Read what the worker has written so far into the buffer, waiting until `deadline`."""
        assert self._process.stdout is not None
        fd = self._process.stdout.fileno()
        remaining = deadline - time.monotonic()
        ready, _, _ = select.select([fd], [], [], max(0.0, remaining))
        if not ready:
            raise DeviceTimeoutError(f"{self.name}: no answer from the worker in time")
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            raise DeviceDisconnectedError(
                f"{self.name}: the worker process exited (code {self._process.wait(timeout=1)}){self._last_error()}"
            )
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
        if self.alive or self._process.stderr is None:
            return ""
        lines = self._process.stderr.read().decode(errors="replace").strip().splitlines()
        return f": {lines[-1]}" if lines else ""

    def stop(self, goodbye: bytes | None, timeout_s: float) -> str:
        """Say `goodbye` (if alive), wait, kill if it lingers; returns its last error line."""
        process = self._process
        try:
            if goodbye is not None and self.alive and process.stdin is not None:
                process.stdin.write(goodbye)
                process.stdin.flush()
            process.wait(timeout=timeout_s)
        except (OSError, subprocess.TimeoutExpired):
            process.kill()
            process.wait(timeout=timeout_s)
        error = self._last_error()
        for stream in (process.stdin, process.stdout, process.stderr):
            if stream is not None:
                stream.close()
        return error.removeprefix(": ")
