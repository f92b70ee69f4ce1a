"""Any projector as an HDMI display: a streaming projector whose patterns a worker process
(drivers.hdmi.worker) puts on the chosen output, reporting when each was presented."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import zlib

import numpy as np

from drivers.base import Projector, ProjectorMode
from drivers.errors import DeviceDisconnectedError, DeviceNotFoundError, DeviceProtocolError, DeviceTimeoutError


class HdmiProjector(Projector):
    """`video_driver` is SDL's: kmsdrm (a bench without a desktop), x11, wayland, or offscreen
    (tests). `last_present_s` is the monotonic time the last pattern reached the display buffer."""

    mode = ProjectorMode.STREAMING

    def __init__(
        self,
        name: str,
        resolution: tuple[int, int],
        display: int = 0,
        video_driver: str = "kmsdrm",
        timeout_s: float = 2.0,
        start_timeout_s: float = 10.0,
    ) -> None:
        super().__init__(name)
        self._resolution = resolution
        self.display = display
        self.video_driver = video_driver
        self.timeout_s = timeout_s
        self.start_timeout_s = start_timeout_s
        self._process: subprocess.Popen[bytes] | None = None
        self.last_present_s: float | None = None
        self.last_checksum: int | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        return self._resolution

    @property
    def worker_pid(self) -> int | None:
        return None if self._process is None else self._process.pid

    def _do_open(self) -> None:
        env = {**os.environ, "SDL_VIDEODRIVER": self.video_driver, "PYGAME_HIDE_SUPPORT_PROMPT": "1"}
        width, height = self._resolution
        self._process = subprocess.Popen(
            [sys.executable, "-m", "drivers.hdmi.worker", str(width), str(height), str(self.display)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
        )
        try:
            if self._read_line(self.start_timeout_s) != "R":
                raise DeviceProtocolError(f"{self.name}: the display worker did not start")
        except (DeviceTimeoutError, DeviceDisconnectedError, DeviceProtocolError) as exc:
            error = self._stop_worker()
            raise DeviceNotFoundError(
                f"{self.name}: no display on {self.video_driver} output {self.display}: {error or exc}"
            ) from exc

    def _do_close(self) -> None:
        self._stop_worker()

    def _stop_worker(self) -> str:
        """Ask the worker to go dark and exit; kill it if it does not. Returns its last error text."""
        process, self._process = self._process, None
        if process is None:
            return ""
        try:
            if process.poll() is None and process.stdin is not None:
                process.stdin.write(b"Q\n")
                process.stdin.flush()
            process.wait(timeout=self.timeout_s)
        except (OSError, subprocess.TimeoutExpired):
            process.kill()
            process.wait(timeout=self.timeout_s)
        stderr = process.stderr.read().decode(errors="replace").strip() if process.stderr else ""
        for stream in (process.stdin, process.stdout, process.stderr):
            if stream is not None:
                stream.close()
        return stderr.splitlines()[-1] if stderr else ""

    def _read_line(self, timeout_s: float) -> str:
        assert self._process is not None and self._process.stdout is not None
        ready, _, _ = select.select([self._process.stdout], [], [], timeout_s)
        if not ready:
            raise DeviceTimeoutError(f"{self.name}: the display worker did not answer within {timeout_s:g} s")
        line = self._process.stdout.readline()
        if not line:
            raise DeviceDisconnectedError(f"{self.name}: the display worker exited (code {self._process.poll()})")
        return line.decode().strip()

    def _send(self, header: bytes, payload: bytes = b"") -> None:
        process = self._process
        if process is None or process.poll() is not None or process.stdin is None:
            raise DeviceDisconnectedError(f"{self.name}: the display worker is not running")
        try:
            process.stdin.write(header + payload)
            process.stdin.flush()
        except (BrokenPipeError, OSError) as exc:
            raise DeviceDisconnectedError(f"{self.name}: the display worker is gone ({exc})") from exc
        reply = self._read_line(self.timeout_s).split()
        if len(reply) != 3 or reply[0] != "P":
            raise DeviceProtocolError(f"{self.name}: unexpected answer from the display worker: {reply}")
        self.last_present_s = float(reply[1])
        self.last_checksum = int(reply[2])

    def _do_show(self, pattern: np.ndarray) -> None:
        data = np.ascontiguousarray(pattern).tobytes()
        self._send(f"S {len(data)}\n".encode(), data)
        if self.last_checksum != zlib.crc32(data):
            raise DeviceProtocolError(f"{self.name}: the display shows something other than the pattern")

    def _do_dark(self) -> None:
        if self._process is not None and self._process.poll() is None:
            self._send(b"D\n")
