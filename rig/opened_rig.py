"""A Rig: the opened devices of a RigConfig, their geometry, and what the rig can do beyond them.

A rig either has or lacks each capability; code asks the rig, never its type:
- `clock`: the clock of frame stamps and presentations, and the way time passes (real time on real
  devices, bench time on the simulated bench);
- `truth`: ground truth of the scene (only a simulated rig has it), for measuring accuracy;
- `scene`: a way to put a calibration board before the cameras (only a simulated rig; on a real
  bench the operator does, and calibration reads the views from a folder).

Rigs are built by rig.assembly.open_rig.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from drivers.base import Camera, Device, Frame, Projector
from drivers.errors import DeviceCancelledError
from rig.config import RigConfig
from rig.errors import ConfigError
from rig.geometry import CameraModel

log = logging.getLogger(__name__)

LATENCY_FILE = "latency.json"  # in the data directory: `slrig doctor --latency` writes, `latency_s: measured` reads


class Clock(Protocol):
    """The time of Frame.timestamp_s and Projector.last_present_s, and how to let it pass."""

    def now(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


class MonotonicClock:
    """Real devices: the host's monotonic clock, and real waiting."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class PixelTruth(Protocol):
    """Ground truth per camera pixel for one (camera, projector) pair; arrays are (H, W[, k])."""

    hit: np.ndarray  # a surface is seen
    points: np.ndarray  # world points, mm (NaN where no hit)
    normals: np.ndarray  # unit normals facing the camera
    depth: np.ndarray  # camera-frame z, mm (0 where no hit)
    projector_uv: np.ndarray  # projector pixel coordinates of the surface point
    lit: np.ndarray  # inside the projector's image, unshadowed and facing it
    albedo: np.ndarray  # (H, W, 3) linear RGB of the surface seen (0 where no hit)
    white_irradiance: np.ndarray  # (H, W) light on the surface under the projector's white frame

    def nearest_distance(self, points: np.ndarray) -> np.ndarray:
        """(N,) distance (mm) of each point (N, 3) to the nearest true surface point the camera sees."""
        ...


class GroundTruth(Protocol):
    """What the scene really is: the devices' true geometry, per-pixel truth, and ray casts."""

    @property
    def cameras(self) -> Sequence[Any]: ...  # true CameraModels, in the config's order

    @property
    def projectors(self) -> Sequence[Any]: ...

    def ground_truth(self, camera: int, projector: int) -> PixelTruth: ...

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First surface hit (points, normals) along each ray; NaN where a ray hits nothing."""
        ...


class SceneControl(Protocol):
    """Puts a printed calibration board (an image, `pixel_mm` per pixel) at a pose before the
    cameras: `axes` (3, 3) are the print's x, y and normal in the world, `origin` its corner."""

    def show_board(self, image: np.ndarray, pixel_mm: float, axes: np.ndarray, origin: np.ndarray) -> None: ...


@dataclass(eq=False)
class Rig:
    """Opened devices and their geometry; close() darkens projectors and closes everything."""

    config: RigConfig
    projectors: list[Projector]
    cameras: list[Camera]
    projector_models: list[CameraModel]
    camera_models: list[CameraModel]
    clock: Clock = field(default_factory=MonotonicClock)
    truth: GroundTruth | None = None
    scene: SceneControl | None = None
    calibration_sha256: str | None = None  # of calibration.file when reconstruction uses one
    response_luts: list[np.ndarray | None] = field(default_factory=list)  # per projector, from response.json
    # per projector, the share of each pixel's light its patterns send (adaptive projection:
    # rig.pipeline.projection_mask); empty: all of it
    intensity_masks: list[np.ndarray] = field(default_factory=list)
    response_sha256: str | None = None
    extras: list[Device] = field(default_factory=list)  # housekeeping (projector power), opened first
    # Called at every wait for light: the daemon's heartbeat and cancel check in long sessions.
    checkpoint: Callable[[], None] | None = field(default=None, repr=False)
    # Set from another thread to cut a wait for a frame short (then the checkpoint raises).
    cancel: threading.Event | None = field(default=None, repr=False)
    # Handed every frame captured (the daemon's camera views): must return at once, copy nothing.
    tap: Callable[[int, Frame], None] | None = field(default=None, repr=False)
    # Terms computed from the geometry once and kept between scans (per-pixel rays of each pair).
    memo: dict[object, object] = field(default_factory=dict, repr=False)
    _closed: bool = field(default=False, repr=False)

    def latency_s(self, projector: int) -> float:
        """The display latency to wait after showing a pattern on `projector`."""
        value = self.config.projectors[projector].latency_s
        if value != "measured":
            return float(value)
        path = self.config.output.data_dir / LATENCY_FILE
        try:
            return float(json.loads(path.read_text())[self.config.projectors[projector].name])
        except (OSError, ValueError, KeyError) as exc:
            raise ConfigError(
                "config",
                [
                    f"projectors[{projector}].latency_s: 'measured', but {path} has no "
                    f"measurement ({exc}); run `slrig doctor --latency`"
                ],
            ) from None

    def wait(self, seconds: float) -> None:
        """Let time pass on the rig's clock, after the checkpoint (which may cancel)."""
        if self.checkpoint is not None:
            self.checkpoint()
        self.clock.sleep(seconds)

    def capture(self, camera: int, timeout_s: float) -> Frame:
        """A frame from camera `camera` (Camera.capture); when `cancel` cuts its wait, the
        checkpoint raises the canceller's exception (else DeviceCancelledError propagates)."""
        device = self.cameras[camera]
        try:
            if self.cancel is None:
                frame = device.capture(timeout_s=timeout_s)
            else:
                frame = device.capture(timeout_s=timeout_s, cancel=self.cancel)
        except DeviceCancelledError:
            if self.checkpoint is not None:
                self.checkpoint()
            raise
        if self.tap is not None:
            self.tap(camera, frame)
        return frame

    def all_dark(self) -> None:
        for projector in self.projectors:
            with contextlib.suppress(Exception):  # darkening the others matters more than this error
                projector.dark()

    def shut_projectors(self, timeout_s: float) -> list[str]:
        """From a thread other than the one using the rig: every projector dark and closed (nothing
        the other thread does lights it again) and the power controls let go, waiting at most
        `timeout_s` in all for calls in flight. Cameras stay as they are: closing one under a
        capture is not safe in every driver. Returns the projectors that still report light."""
        deadline = time.monotonic() + timeout_s
        for projector in self.projectors:
            if not projector.shut(deadline - time.monotonic()):
                log.error("%s: a call did not end within the shutdown timeout; darkened regardless", projector.name)
        for device in self.extras:
            with contextlib.suppress(Exception):
                device.close()
        return self.lit()

    def lit(self) -> list[str]:
        """The projectors whose drivers report light now (those that cannot tell are not named)."""
        return [p.name for p in self.projectors if getattr(p, "is_dark", True) is False]

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.all_dark()
        for device in (*self.projectors, *self.cameras, *self.extras):
            with contextlib.suppress(Exception):  # close every device even if one fails
                device.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
