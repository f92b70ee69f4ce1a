"""Aim mode: the projectors show a setup pattern and every camera captures as fast as it delivers,
for aiming, focusing and setting exposure in the console's camera views (rig.service.frames).

Run by the job worker, like live mode, whenever no job waits; a queued job pauses it. It needs a
time limit (the console renews it while its page is open), so a closed browser never leaves a
test pattern lit: when it passes, the projectors go dark.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.config import RigConfig
from rig.errors import ConfigError
from rig.opened_rig import Rig
from rig.patterns import SETUP_PATTERNS, codec_class, setup_pattern
from rig.service.errors import JobConflictError, SetupRefusedError
from rig.service.modes import WorkerMode

MAX_AIM_S = 3600.0
FRAME_TIMEOUT_S = 2.0


@dataclass(frozen=True)
class AimRequest:
    """What the projectors show: a setup pattern, or pattern `index` of `codec`'s scan; on
    projector `projector` (the others dark), or on all of them (None)."""

    pattern: str = "white"
    projector: int | None = None
    square_px: int = 32
    codec: str | None = None
    index: int = 0

    def images(self, config: RigConfig) -> list[np.ndarray]:
        """The image per projector; SetupRefusedError (or a setup pattern's ValueError) naming what does not fit."""
        out = []
        for p, projector in enumerate(config.projectors):
            size = (int(projector.resolution[0]), int(projector.resolution[1]))
            if self.projector is not None and p != self.projector:
                out.append(setup_pattern("black", size))
            elif self.pattern == "codec":
                out.append(_codec_pattern(config, size, self.codec, self.index))
            else:
                out.append(setup_pattern(self.pattern, size, self.square_px))
        return out


def _codec_pattern(config: RigConfig, size: tuple[int, int], codec: str | None, index: int) -> np.ndarray:
    name = codec or config.scan.codec
    try:
        scan = config.with_codec(name).scan
    except ConfigError as exc:
        raise SetupRefusedError(f"codec: {name} does not fit this rig: {'; '.join(exc.problems)}") from None
    instance = codec_class(name)(size, getattr(scan, name, None))
    if not 0 <= index < instance.frame_count:
        raise SetupRefusedError(f"index: {name} has patterns 0 to {instance.frame_count - 1}, not {index}")
    for k, image in enumerate(instance.iter_patterns()):
        if k == index:
            return image
    raise SetupRefusedError(f"index: {name} made fewer patterns than it counts")  # pragma: no cover - a codec's bug


class AimMode(WorkerMode):
    """Whether aim mode is wanted (the AimRequest) and until when, what it shows, and its state
    (thread-safe)."""

    def __init__(self, config: RigConfig, worker: threading.Condition) -> None:
        super().__init__(worker)
        self.config = config
        self._version = 0
        self._images: list[np.ndarray] = []

    def start(self, request: AimRequest, seconds: float, live_running: bool) -> dict[str, Any]:
        """Want aim mode showing `request` for `seconds`; starting again changes the pattern and
        renews the time limit. JobConflictError while live mode runs (both need the whole rig),
        SetupRefusedError for a pattern that does not fit the rig."""
        if live_running:
            raise JobConflictError("live mode is running; stop it (DELETE /v1/live) to aim")
        if request.pattern not in (*SETUP_PATTERNS, "codec"):
            raise SetupRefusedError(f"pattern: one of {', '.join(SETUP_PATTERNS)} or codec, not {request.pattern!r}")
        if request.projector is not None and not 0 <= request.projector < len(self.config.projectors):
            raise SetupRefusedError(f"projector: this rig has {len(self.config.projectors)} projectors")
        try:
            images = request.images(self.config)
        except ValueError as exc:  # a setup pattern's size
            raise SetupRefusedError(str(exc)) from None
        with self._lock:
            if request != self._wanted:
                self._version += 1
                self._images = images
            self._want(request, min(seconds, MAX_AIM_S))
        self._wake_worker()
        return self.view()

    def run(self, rig: Rig, jobs_waiting: Callable[[], bool], between: Callable[[], None]) -> None:
        """Show the pattern and capture every camera in turn while wanted and no job waits;
        `between` runs before each round (heartbeat, camera settings). Projectors dark at the end."""
        shown, period = -1, frame_period_s(self.config)
        with self._lock:
            self._state = "running"
        try:
            while True:
                between()
                with self._lock:
                    version, images = self._version, self._images
                if not self.wanted() or jobs_waiting():
                    break
                if version != shown:
                    _show(rig, images)
                    shown = version
                started = time.monotonic()
                for camera in range(len(rig.cameras)):
                    rig.capture(camera, FRAME_TIMEOUT_S)
                time.sleep(max(0.0, period - (time.monotonic() - started)))  # the simulator renders faster
        except BaseException as exc:
            with self._lock:
                self._wanted, self._state, self._reason = None, "failed", str(exc) or type(exc).__name__
            raise
        finally:
            rig.all_dark()
        with self._lock:
            if self._wanted is not None:
                self._state, self._reason = "paused", "a job is running"
            else:
                self._state = "off"

    def view(self) -> dict[str, Any]:
        with self._lock:
            wanted = self._wanted
            left = None if wanted is None or self._deadline is None else max(0.0, self._deadline - time.monotonic())
            return {
                "state": self._state,
                "reason": self._reason,
                "pattern": None if wanted is None else wanted.__dict__,
                "seconds_left": None if left is None else round(left, 3),
            }


def _show(rig: Rig, images: list[np.ndarray]) -> None:
    for projector, image in zip(rig.projectors, images, strict=True):
        projector.show_still(image)  # a sequence projector leaves its sequence for a plain display


def frame_period_s(config: RigConfig) -> float:
    """The fastest configured camera's frame period: aim mode captures no faster."""
    periods = []
    for camera in config.cameras:
        if camera.driver == "oak":
            periods.append(1.0 / camera.oak.fps)
        elif camera.driver == "v4l2" and camera.v4l2 is not None:
            periods.append(camera.v4l2.frame_period_s)
        else:
            periods.append(camera.sim.frame_period_s)
    return min(periods, default=1 / 30)
