"""A camera that plays recorded frames: a folder of images (a saved scan's frames, another system's
captures) or frames held in memory, at a set rate, as a real camera delivers them. For demos,
regression runs of real captures, and a pipeline change tried on last week's data.

With `advance: capture` (the default), and whenever it is triggered (EXTERNAL), each capture
takes the source's next frame, no sooner than a frame period after the last: one frame per
pattern, in order, as a projector's trigger output would give them, so a scan of the recorded
patterns meets the frames recorded for them. With `advance: clock` it runs free: frame k of the
source, looping, is exposed at t0 + k / rate from the moment it opens; a capture returns the
oldest of the `buffered_frames` the driver holds (as a V4L2 driver does: stale after a pause) or,
holding none, the next frame to complete; `flush` drops what it holds. Frame numbers count the
frames the camera exposed, so skipped frames show as gaps; stamps are the end of each exposure on
the host's monotonic clock. A source played to its end without `loop` goes silent: the next
capture fails at its timeout, as a stalled camera does.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from drivers.base import Camera, Frame
from drivers.errors import DeviceDisconnectedError, DeviceError, DeviceTimeoutError
from drivers.faults import Fault, FaultPlan
from drivers.options import DeviceConfig, ReplayOptions
from drivers.sequences import TriggerMode

IMAGE_SUFFIXES = (".png", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg", ".pgm")


def natural_key(path: Path) -> list[object]:
    """frame_2 before frame_10."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]


def source_files(folder: Path, pattern: str) -> list[Path]:
    """The folder's images matching `pattern`, in natural order; DeviceError naming the folder
    where there are none."""
    if not folder.is_dir():
        raise DeviceError(f"replay source {folder}: not a folder")
    found = [p for p in folder.glob(pattern) if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    if not found:
        raise DeviceError(f"replay source {folder}: no images match {pattern!r}")
    return sorted(found, key=natural_key)


class ReplayCamera(Camera):
    """Recorded frames, played as a camera delivers them (see the module docstring)."""

    @classmethod
    def from_config(cls, device: DeviceConfig) -> ReplayCamera:
        """The camera a config's `replay` section and camera settings describe."""
        return cls(
            device.name, device.resolution, device.replay, exposure_us=device.exposure_us, bit_depth=device.bit_depth
        )

    def __init__(
        self,
        name: str,
        resolution: tuple[int, int],
        options: ReplayOptions,
        frames: Sequence[np.ndarray] | None = None,
        exposure_us: float = 10000.0,
        bit_depth: int = 8,
    ) -> None:
        super().__init__(name)
        self._resolution = (int(resolution[0]), int(resolution[1]))
        self.options = options
        self._memory = list(frames) if frames is not None else None
        self._files: list[Path] = []
        self._exposure_us = exposure_us
        self._bit_depth = bit_depth
        self._fault: FaultPlan | None = None

    def inject(self, plan: FaultPlan) -> None:
        """A fault as the protocol fakes take it (drivers.faults), counted in frames."""
        self._fault = plan

    @property
    def resolution(self) -> tuple[int, int]:
        return self._resolution

    @property
    def frame_count(self) -> int:
        """Frames in the source."""
        return len(self._memory) if self._memory is not None else len(self._files)

    def _do_open(self) -> None:
        if self._memory is None:
            if self.options.source is None:
                raise DeviceError(f"{self.name}: replay.source: no folder given and no frames in memory")
            self._files = source_files(Path(self.options.source), self.options.files)
        if self.frame_count == 0:
            raise DeviceError(f"{self.name}: the replay source holds no frames")
        first = self._image(0)
        if (first.shape[1], first.shape[0]) != self._resolution:
            raise DeviceError(
                f"{self.name}: the replay source's frames are {first.shape[1]}x{first.shape[0]}, the camera is "
                f"configured {self._resolution[0]}x{self._resolution[1]}"
            )
        self._t0 = time.monotonic()
        self._exposed = 0  # frames exposed so far (free-running: by the clock; triggered: by capture)
        self._delivered = -1  # the index of the last frame handed out
        self._last_due = -math.inf  # when it ended
        self._flushed_at: float | None = None

    def _do_close(self) -> None:
        pass

    def _do_set_trigger(self, mode: TriggerMode) -> None:
        self._t0 = time.monotonic()
        self._delivered, self._last_due = -1, -math.inf

    def _do_flush(self) -> None:
        self._flushed_at = time.monotonic()

    def _period(self) -> float:
        return 1.0 / self.options.rate_hz

    def _do_capture(self, deadline: float) -> Frame:
        if self.trigger is TriggerMode.EXTERNAL or self.options.advance == "capture":
            index = self._delivered + 1
            due = max(
                self._last_due + self._period(), time.monotonic() + self._exposure_us * 1e-6
            )  # exposed after the call
        else:
            index, due = self._free_running_index()
        self._check_fault(index, deadline)
        if not self.options.loop and index >= self.frame_count:
            self._wait_until(deadline)
            raise DeviceTimeoutError(f"{self.name}: the replay source's {self.frame_count} frames are played")
        if due > deadline:
            self._wait_until(deadline)
            raise DeviceTimeoutError(f"{self.name}: the next frame completes after the capture deadline")
        self._wait_until(due)
        self._last_due = due
        self._delivered = index
        self._flushed_at = None
        return Frame(
            image=self._image(index % self.frame_count),
            timestamp_s=due,
            sequence=index + 1,
            exposure_us=self._exposure_us,
            gain=1.0,
            bit_depth=self._bit_depth,
        )

    def _free_running_index(self) -> tuple[int, float]:
        """The frame a free-running capture now returns, and when its exposure ends."""
        now = time.monotonic()
        completed = math.floor((now - self._t0) / self._period())  # frames 0 .. completed-1 are done
        held = self.options.buffered_frames
        if self._flushed_at is not None:  # nothing held: the first frame completed after the flush
            index = math.floor((self._flushed_at - self._t0) / self._period())
        elif held > 0:
            index = max(self._delivered + 1, completed - held)
        else:
            index = max(self._delivered + 1, completed)
        return index, self._t0 + (index + 1) * self._period()

    def _check_fault(self, index: int, deadline: float) -> None:
        plan = self._fault
        if plan is None or self._delivered + 1 < plan.after:
            return
        if plan.fault is Fault.SILENCE:
            self._wait_until(deadline)
            raise DeviceTimeoutError(f"{self.name}: no frame before the capture deadline")
        raise DeviceDisconnectedError(f"{self.name}: the replay source is gone")

    def _image(self, index: int) -> np.ndarray:
        if self._memory is not None:
            return self._memory[index]
        path = self._files[index]
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise DeviceError(f"{self.name}: replay frame {path} cannot be read")
        if image.ndim == 3 and image.shape[2] == 4:
            image = image[..., :3]
        return image


def machine_problems(device: DeviceConfig) -> list[str]:
    """The recorded frames' folder is there, and holds images (slrig doctor)."""
    source = device.replay.source if device.replay is not None else None
    if source is None:
        return []
    folder = Path(source)
    if not folder.is_dir():
        return [f"replay.source {folder}: no such folder"]
    if not any(folder.glob(device.replay.files)):
        return [f"replay.source {folder}: no file matches {device.replay.files!r}"]
    return []
