"""Any projector as an HDMI display: a streaming projector whose patterns a worker process
(drivers.hdmi.worker) puts on the chosen output, reporting when each was presented."""

from __future__ import annotations

import glob
import os
import zlib

import numpy as np

from drivers.base import Projector, ProjectorMode
from drivers.childproc import WorkerDevice, WorkerProcess
from drivers.errors import DeviceDisconnectedError, DeviceNotFoundError, DeviceProtocolError, DeviceTimeoutError
from drivers.machine import package_problem
from drivers.options import DeviceConfig


class HdmiProjector(WorkerDevice, Projector):
    """`video_driver` is SDL's: kmsdrm (a bench without a desktop), x11, wayland, or offscreen
    (tests). `last_present_s` is the monotonic time the last pattern reached the display buffer."""

    mode = ProjectorMode.STREAMING

    @classmethod
    def from_config(cls, device: DeviceConfig) -> HdmiProjector:
        """The projector a config's `hdmi` section describes."""
        h = device.hdmi
        return cls(device.name, device.resolution, h.display, h.video_driver, start_timeout_s=h.start_timeout_s)

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
        self._worker: WorkerProcess | None = None
        self.last_present_s: float | None = None
        self.last_checksum: int | None = None  # of the displayed image, as the worker read it back
        self._black_checksum = zlib.crc32(bytes(resolution[0] * resolution[1]))

    @property
    def is_dark(self) -> bool:
        """Whether the worker last read back a black screen."""
        return self.last_checksum == self._black_checksum

    def _do_open(self) -> None:
        self._start_worker()
        self._do_dark()  # confirm the new output is black

    def _start_worker(self) -> None:
        """A new worker owns the output; it starts black."""
        width, height = self._resolution
        self._worker = WorkerProcess(
            self.name,
            "drivers.hdmi.worker",
            [str(width), str(height), str(self.display)],
            {"SDL_VIDEODRIVER": self.video_driver, "PYGAME_HIDE_SUPPORT_PROMPT": "1"},
        )
        try:
            if self._worker.read_line(self.start_timeout_s).strip() != b"R":
                raise DeviceProtocolError(f"{self.name}: the display worker did not start")
        except (DeviceTimeoutError, DeviceDisconnectedError, DeviceProtocolError) as exc:
            worker, self._worker = self._worker, None
            error = worker.stop(None, self.timeout_s)
            raise DeviceNotFoundError(
                f"{self.name}: no display on {self.video_driver} output {self.display}: {error or exc}"
            ) from exc

    def _do_close(self) -> None:
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.stop(b"Q\n", self.timeout_s)  # the worker goes black before it exits

    def _send(self, header: bytes, payload: bytes = b"") -> None:
        if self._worker is None:
            raise DeviceDisconnectedError(f"{self.name}: the display worker is not running")
        try:
            self._worker.send(header + payload, self.timeout_s)
            reply = self._worker.read_line(self.timeout_s).decode(errors="replace").split()
            if len(reply) != 3 or reply[0] != "P":
                raise DeviceProtocolError(f"{self.name}: unexpected answer from the display worker: {reply}")
        except (DeviceTimeoutError, DeviceProtocolError):
            # Out of step (a late answer may still come): abandon this worker; dark() starts a new one.
            worker, self._worker = self._worker, None
            worker.stop(None, self.timeout_s)
            raise
        self.last_present_s = float(reply[1])
        self.last_checksum = int(reply[2])

    def _do_show(self, pattern: np.ndarray) -> None:
        data = np.ascontiguousarray(pattern).tobytes()
        self._send(f"S {len(data)}\n".encode(), data)
        if self.last_checksum != zlib.crc32(data):
            raise DeviceProtocolError(f"{self.name}: the display shows something other than the pattern")

    def show_rgb(self, frame: np.ndarray) -> None:
        """Show a colour frame (uint8, height x width x 3, RGB): a LightCrafter's video input
        carries one pattern per colour channel."""
        self._require_open()
        width, height = self._resolution
        if frame.shape != (height, width, 3) or frame.dtype != np.uint8:
            raise ValueError(f"{self.name}: frame must be uint8 of shape {(height, width, 3)}, got {frame.shape}")
        data = np.ascontiguousarray(frame).tobytes()

        def show() -> None:
            self._send(f"C {len(data)}\n".encode(), data)
            if self.last_checksum != zlib.crc32(data):
                raise DeviceProtocolError(f"{self.name}: the display shows something other than the frame")

        self._guarded(show)

    def _do_dark(self) -> None:
        if self._worker is not None and self._worker.alive:
            self._send(b"D\n")
            if self.last_checksum != self._black_checksum:
                raise DeviceProtocolError(f"{self.name}: the display is not black after dark")
            return
        if not self._open and self._worker is None:
            return  # closed: nothing to hold
        # The worker died (killed, crashed): whatever the output shows now is not under control.
        # A new worker takes the output and holds it black, the safe state.
        if self._worker is not None:
            self._worker.stop(None, self.timeout_s)
            self._worker = None
        self._start_worker()
        self._send(b"D\n")  # and confirm it is black


def machine_problems(device: DeviceConfig) -> list[str]:
    """What this machine lacks to show a config's `hdmi` output: under kmsdrm, a GPU's output it may
    open, and pygame-ce (slrig doctor)."""
    if device.hdmi.video_driver != "kmsdrm":
        return []
    found = []
    cards = glob.glob("/dev/dri/card*")
    if not cards:
        found.append("no /dev/dri/card*: no display output (kmsdrm needs a GPU with a connected output)")
    elif not any(os.access(c, os.R_OK | os.W_OK) for c in cards):
        found.append("no access to /dev/dri: add the service user to the 'video' group")
    pygame = package_problem("pygame", "pip install 'slrig[hdmi]'", "pygame-ce")
    return found + ([pygame] if pygame else [])
