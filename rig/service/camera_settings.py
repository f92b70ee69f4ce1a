"""Exposure and gain set from the console or over REST: kept by the service and given to every rig
it opens, so a scan uses what the operator set while aiming.

Only the job worker touches the devices (rig.service.worker_calls): a request waits a bounded time
for the worker to send the values. The driver's refusal (out of its range, no gain control) comes
back to the request and the kept values stay as they were.
"""

from __future__ import annotations

import threading
from typing import Any

from rig.config import RigConfig
from rig.opened_rig import Rig
from rig.service.errors import SetupRefusedError
from rig.service.worker_calls import WorkerCalls


class CameraSettings:
    """Per camera index: the exposure and gain the operator set (beyond the config's)."""

    def __init__(self, config: RigConfig, calls: WorkerCalls) -> None:
        self.config = config
        self._calls = calls
        self._lock = threading.Lock()
        self._kept: dict[int, dict[str, float]] = {}

    def kept(self, camera: int) -> dict[str, float]:
        with self._lock:
            return dict(self._kept.get(camera, {}))

    def request(self, camera: int, values: dict[str, float], busy: str | None) -> dict[str, float]:
        """Send `values` (exposure_us, gain) to camera `camera` through the worker; `busy` names the
        job running (then nothing changes: JobConflictError). SetupRefusedError with the driver's reason."""

        def send(rig: Rig) -> None:
            _send(rig, camera, values)
            with self._lock:
                self._kept.setdefault(camera, {}).update(values)

        self._calls.call(send, busy, "camera settings")
        return self.kept(camera)

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
