"""Exposure and gain set from the console or over REST: kept by the service and given to every rig
it opens, so a scan uses what the operator set while aiming.

Only the job worker touches the devices: a request records the wanted values and waits (a bounded
time) for the worker to send them between jobs or between aim or live frames. The driver's refusal
(out of its range, no gain control) comes back to the request and the kept values stay as they were.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

from drivers.errors import DeviceError
from rig.config import RigConfig
from rig.rig import Rig
from rig.service.errors import JobConflictError, SetupRefusedError

APPLY_TIMEOUT_S = 15.0  # opening a rig takes seconds (cameras, the simulator's first ray cast)


@dataclass
class _Request:
    camera: int
    values: dict[str, float]
    done: threading.Event
    error: str | None = None


class CameraSettings:
    """Per camera index: the exposure and gain the operator set (beyond the config's)."""

    def __init__(self, config: RigConfig, worker: threading.Condition) -> None:
        self.config = config
        self._worker = worker
        self._lock = threading.Lock()
        self._kept: dict[int, dict[str, float]] = {}
        self._pending: list[_Request] = []

    def kept(self, camera: int) -> dict[str, float]:
        with self._lock:
            return dict(self._kept.get(camera, {}))

    def request(self, camera: int, values: dict[str, float], busy: str | None) -> dict[str, float]:
        """Send `values` (exposure_us, gain) to camera `camera` through the worker; `busy` names the
        job running (then nothing changes: JobConflictError). SetupRefusedError with the driver's reason."""
        if busy is not None:
            raise JobConflictError(f"job {busy} is running; camera settings change between jobs")
        request = _Request(camera, values, threading.Event())
        with self._lock:
            self._pending.append(request)
        with self._worker:
            self._worker.notify_all()
        if not request.done.wait(APPLY_TIMEOUT_S):
            with self._lock:
                if request in self._pending:
                    self._pending.remove(request)
            raise JobConflictError(f"the rig did not take the settings within {APPLY_TIMEOUT_S:g} s (busy)")
        if request.error is not None:
            raise SetupRefusedError(request.error)
        return self.kept(camera)

    def pending(self) -> bool:
        with self._lock:
            return bool(self._pending)

    def apply_pending(self, rig: Rig) -> None:
        """The worker: send waiting requests to `rig`'s cameras, then answer them."""
        with self._lock:
            waiting, self._pending = self._pending, []
        for request in waiting:
            try:
                _send(rig, request.camera, request.values)
            except (ValueError, DeviceError, SetupRefusedError) as exc:
                request.error = str(exc)
            else:
                with self._lock:
                    self._kept.setdefault(request.camera, {}).update(request.values)
            request.done.set()

    def fail_pending(self, reason: str) -> None:
        """The worker could not reach the cameras: every waiting request is answered `reason`."""
        with self._lock:
            waiting, self._pending = self._pending, []
        for request in waiting:
            request.error = reason
            request.done.set()

    def apply_kept(self, rig: Rig) -> None:
        """A rig just opened: every kept value to its camera (a refusal propagates)."""
        with self._lock:
            kept = {camera: dict(values) for camera, values in self._kept.items()}
        for camera, values in kept.items():
            _send(rig, camera, values)

    def views(self, rig: Rig | None) -> list[dict[str, Any]]:
        """Each camera: its exposure and gain (kept, else the open device's, else the config's) and
        whether its driver has a gain control (None until the rig has been opened)."""
        out = []
        for i, camera in enumerate(self.config.cameras):
            device = rig.cameras[i] if rig is not None and i < len(rig.cameras) else None
            kept = self.kept(i)
            exposure = kept.get("exposure_us", device.exposure_us if device else camera.exposure_us)
            gain = kept.get("gain", device.gain if device is not None else camera.gain)
            out.append(
                {
                    "index": i,
                    "name": camera.name,
                    "driver": camera.driver,
                    "resolution": list(camera.resolution),
                    "exposure_us": exposure,
                    "gain": gain,
                    "has_gain": None if device is None else device.has_gain,
                }
            )
        return out


def _send(rig: Rig, camera: int, values: dict[str, float]) -> None:
    if not 0 <= camera < len(rig.cameras):
        raise SetupRefusedError(f"camera {camera}: this rig has {len(rig.cameras)} cameras")
    device = rig.cameras[camera]
    if "exposure_us" in values:
        device.set_exposure_us(values["exposure_us"])
    if "gain" in values:
        device.set_gain(values["gain"])
