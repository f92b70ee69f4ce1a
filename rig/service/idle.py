"""What the job worker does while no job waits: the device calls requests wait for (camera
settings, projector power), then live mode or aim mode if one is wanted (live first: it was asked
for to measure, aim mode only to look)."""

from __future__ import annotations

import logging
from collections.abc import Callable

from drivers.base import Frame
from drivers.errors import DeviceError
from rig.errors import CaptureFaultError
from rig.opened_rig import Rig
from rig.service.aim import AimMode
from rig.service.camera_settings import CameraSettings
from rig.service.errors import JobCancelledError
from rig.service.live import LiveMode
from rig.service.stopping import WorkerRig
from rig.service.worker_calls import WorkerCalls

log = logging.getLogger(__name__)


class IdleWork:
    def __init__(
        self,
        rigs: WorkerRig,
        live: LiveMode,
        aim: AimMode,
        settings: CameraSettings,
        calls: WorkerCalls,
        checkpoint: Callable[[], None],
        jobs_waiting: Callable[[], bool],
        on_fault: Callable[[str], None],
    ) -> None:
        """`checkpoint`: the worker's heartbeat and cancel check; `on_fault`: a device fault to
        report (GET /v1/rig) until a job succeeds."""
        self.rigs, self.live, self.aim, self.settings, self.calls = rigs, live, aim, settings, calls
        self._checkpoint, self._jobs_waiting, self._on_fault = checkpoint, jobs_waiting, on_fault

    def prepare(self, rig: Rig, tap: Callable[[int, Frame], None]) -> None:
        """A rig the worker has just opened: every frame it captures goes to `tap` (the camera
        views), and the camera settings the operator set apply to it."""
        rig.tap = tap
        self.settings.apply_kept(rig)

    def wanted(self) -> bool:
        return self.calls.pending() or self.live.wanted() or self.aim.wanted()

    def run(self) -> None:
        for step in (self._calls, self._live, self._aim):
            try:
                step()
            except JobCancelledError:
                self.rigs.darken()
                return
            except Exception as exc:
                if isinstance(exc, (DeviceError, CaptureFaultError)) or isinstance(exc.__cause__, DeviceError):
                    self._on_fault(str(exc))
                log.error("%s failed: %s", step.__name__.strip("_"), exc)
                self.rigs.drop()
                return

    def _between(self) -> None:
        self._checkpoint()
        if self.calls.pending() and self.rigs.rig is not None:
            self.calls.run_pending(self.rigs.rig)

    def _calls(self) -> None:
        if not self.calls.pending():
            return
        try:
            rig = self.rigs.open()
        except Exception as exc:
            self.calls.fail_pending(f"the rig could not be opened: {exc}")
            raise
        self.calls.run_pending(rig)

    def _live(self) -> None:
        if self.live.wanted():
            self.live.run(self.rigs.open(), self._jobs_waiting, self._between)

    def _aim(self) -> None:
        if self.aim.wanted() and not self.live.wanted():
            self.aim.run(self.rigs.open(), self._jobs_waiting, self._between)
