"""A Luxonis OAK camera: depthai runs in a supervised worker process (drivers.oak.worker), so a
native abort or a hung link fails the scan with a DeviceError and leaves the daemon running."""

from __future__ import annotations

import json
import time
from typing import Any

import numpy as np

from drivers.base import Camera, Frame
from drivers.childproc import WorkerDevice, WorkerProcess
from drivers.errors import (
    DeviceDisconnectedError,
    DeviceError,
    DeviceNotFoundError,
    DeviceProtocolError,
    DeviceTimeoutError,
)
from drivers.machine import UDEV_RULES, package_problem
from drivers.options import DeviceConfig
from drivers.sequences import TriggerMode

_ERRORS: dict[str, type[DeviceError]] = {
    "notfound": DeviceNotFoundError,
    "timeout": DeviceTimeoutError,
    "disconnected": DeviceDisconnectedError,
    "protocol": DeviceProtocolError,
}


class OakCamera(WorkerDevice, Camera):
    """One camera socket of an OAK (CAM_A colour, CAM_B / CAM_C mono on an OAK-D) as a mono stream
    with manual exposure and, for global-shutter sensors, external trigger (FSIN). `backend` is
    "depthai", or "fake" for tests and demos without the device."""

    @classmethod
    def from_config(cls, device: DeviceConfig) -> OakCamera:
        """The camera a config's `oak` section and camera settings describe."""
        o = device.oak
        return cls(
            device.name, device.resolution, o.device_id, o.socket, device.exposure_us, o.iso, o.focus, o.fps, o.backend
        )

    def __init__(
        self,
        name: str,
        resolution: tuple[int, int],
        device_id: str | None = None,
        socket: str = "CAM_B",
        exposure_us: float = 10000.0,
        iso: int = 400,
        focus: int | None = None,
        fps: float = 30.0,
        backend: str = "depthai",
        open_timeout_s: float = 20.0,
        env: dict[str, str] | None = None,
    ) -> None:
        super().__init__(name)
        self._resolution = resolution
        self.device_id, self.socket, self.iso, self.focus, self.fps = device_id, socket, iso, focus, fps
        self._exposure_us = exposure_us
        self.backend = backend
        self.open_timeout_s = open_timeout_s
        self._env = env or {}
        self._worker: WorkerProcess | None = None

    def _request(self, answer_within_s: float, **request: Any) -> dict[str, Any]:
        if self._worker is None:
            raise DeviceDisconnectedError(f"{self.name}: the OAK worker is not running")
        try:
            self._worker.send(json.dumps(request).encode() + b"\n")
            line = self._worker.read_line(answer_within_s)
            try:
                answer = json.loads(line)
            except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError
                raise DeviceProtocolError(f"{self.name}: garbled answer from the OAK worker") from exc
        except (DeviceTimeoutError, DeviceProtocolError):
            self._abandon()
            raise
        if not answer.get("ok"):
            raise _ERRORS.get(answer.get("kind"), DeviceError)(f"{self.name}: {answer.get('error')}")
        return answer

    def _abandon(self) -> None:
        """After a timeout the channel is out of step (the late answer may still come): end it."""
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.stop(None, 2.0)

    def _start(self, external_trigger: bool) -> None:
        self._worker = WorkerProcess(self.name, "drivers.oak.worker", [], self._env)
        width, height = self._resolution
        try:
            self._request(
                self.open_timeout_s,
                cmd="open",
                backend=self.backend,
                device_id=self.device_id,
                socket=self.socket,
                width=width,
                height=height,
                fps=self.fps,
                exposure_us=round(self._exposure_us),
                iso=self.iso,
                focus=self.focus,
                external_trigger=external_trigger,
            )
        except DeviceError:
            self._stop()
            raise

    def _stop(self) -> None:
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.stop(b'{"cmd": "close"}\n', 5.0)

    def _do_open(self) -> None:
        self._start(external_trigger=False)

    def _do_close(self) -> None:
        self._stop()

    def _do_set_trigger(self, mode: TriggerMode) -> None:
        # FSIN snapshot mode is set when the pipeline starts: restart it in the new mode.
        self._stop()
        self._start(external_trigger=mode is TriggerMode.EXTERNAL)

    def _do_set_exposure_us(self, exposure_us: float) -> None:
        self._request(5.0, cmd="exposure", exposure_us=round(exposure_us), iso=self.iso)

    has_gain = True  # as ISO: gain 1.0 is ISO 100 (depthai's manual exposure takes both together)
    has_exposure = True
    exposure_range_us = (1.0, 33_000.0)  # depthai's manual exposure (Luxonis: "exposure time 1..33000 us")

    @property
    def gain(self) -> float:
        return self.iso / 100.0

    def set_gain(self, gain: float) -> None:
        super().set_gain(gain)
        self.iso = _iso(gain)  # what the next start sends, open or not

    def _do_set_gain(self, gain: float) -> None:
        self._request(5.0, cmd="exposure", exposure_us=round(self._exposure_us), iso=_iso(gain))

    def _do_flush(self) -> None:
        self._request(5.0, cmd="drain")

    def _do_capture(self, deadline: float) -> Frame:
        remaining = max(0.01, deadline - time.monotonic())
        # The worker waits up to `remaining` for a frame; give its answer a little longer to arrive.
        answer = self._request(remaining + 2.0, cmd="frame", timeout_s=remaining)
        assert self._worker is not None
        try:
            data = self._worker.read_exact(int(answer["size"]), 5.0)
        except DeviceTimeoutError:
            self._abandon()
            raise
        image = np.frombuffer(data, dtype=np.uint8).reshape(answer["shape"])
        return Frame(
            image=image,
            timestamp_s=float(answer["timestamp"]),
            sequence=int(answer["sequence"]),
            exposure_us=float(answer["exposure_us"]),
            gain=float(self.iso) / 100.0,
            bit_depth=8,
        )


def _iso(gain: float) -> int:
    return max(100, min(1600, round(gain * 100)))  # the range depthai's setManualExposure takes


def machine_problems(device: DeviceConfig) -> list[str]:
    """DepthAI, and the udev rules that let the service user open an OAK (slrig doctor)."""
    if device.oak.backend != "depthai":
        return []
    found = [p for p in (package_problem("depthai", "pip install depthai"),) if p]
    if not UDEV_RULES.exists():
        found.append(f"{UDEV_RULES} is missing: install systemd/60-slrig.rules (OAKs need plugdev access)")
    return found
