"""The device interfaces every projector and camera implements, real or simulated.

Public methods hold the shared logic (state checks, validation, keeping the projector dark after a
fault) and call the `_do_*` methods that each driver implements. One thread drives a device; a
projector may also be darkened and closed from another (a daemon stopping while its worker computes),
and a camera's wait for a frame cut short from another (Camera.capture's `cancel`).
"""

from __future__ import annotations

import abc
import contextlib
import enum
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import DeviceCancelledError, DeviceStateError
from drivers.sequences import PatternSequence, TriggerMode


class ProjectorMode(enum.Enum):
    """How a projector gets its patterns."""

    STREAMING = "streaming"  # shows any image it is sent, now (HDMI display output)
    SEQUENCE = "sequence"  # preloads a sequence and steps through it on a trigger (DLP LightCrafter)


@dataclass(frozen=True)
class Frame:
    """One captured image.

    `image` is uint8 or uint16, shape (H, W) for mono or (H, W, 3) for colour (BGR).
    `timestamp_s` is the end of the exposure on the host's monotonic clock (bench time on the
    simulated bench; V4L2 buffer and DepthAI frame stamps are taken there too), so it compares with
    a projector's `last_present_s`. `sequence` counts frames the camera delivered, so gaps show drops.
    `bit_depth` is the sensor's (a 12-bit image is stored in uint16 with values up to 4095).
    """

    image: np.ndarray
    timestamp_s: float
    sequence: int
    exposure_us: float
    gain: float
    bit_depth: int = 8
    meta: dict[str, object] = field(default_factory=dict)

    @property
    def full_scale(self) -> int:
        return (1 << self.bit_depth) - 1

    @property
    def exposure_start_s(self) -> float:
        return self.timestamp_s - self.exposure_us * 1e-6


class Device(abc.ABC):
    """Lifecycle shared by all devices: open, use, close. `close()` is idempotent."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._open = False

    @property
    def is_open(self) -> bool:
        return self._open

    def open(self) -> None:
        if not self._open:
            self._do_open()
            self._open = True

    def close(self) -> None:
        if self._open:
            try:
                self._do_close()
            finally:
                self._open = False

    def _require_open(self) -> None:
        if not self._open:
            raise DeviceStateError(f"{self.name}: device is not open")

    def __enter__(self) -> Device:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @abc.abstractmethod
    def _do_open(self) -> None: ...

    @abc.abstractmethod
    def _do_close(self) -> None: ...


class Projector(Device):
    """A projector shows 8-bit grayscale patterns of its native resolution. Its calls run one at a
    time, whichever thread makes them, so that `shut` from another thread neither interleaves with a
    pattern being sent nor is undone by one sent after it (a closed projector shows nothing)."""

    mode: ProjectorMode = ProjectorMode.STREAMING
    # When the last pattern reached the output, on the clock of Frame.timestamp_s; None if the
    # driver cannot tell. Light is on the scene from here plus the display latency.
    last_present_s: float | None = None

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._calls = threading.RLock()  # re-entrant: close() darkens, a fault in show() darkens

    def close(self) -> None:
        with self._calls:
            super().close()

    def shut(self, timeout_s: float) -> bool:
        """Dark and closed, from any thread: waits up to `timeout_s` for a call in flight to end.
        False when none ended in time (a wedged driver): then it is darkened and closed regardless,
        since light matters more than that call (decision 0002)."""
        got = self._calls.acquire(timeout=max(0.0, timeout_s))
        try:  # the driver's steps, not dark() and close(): without the lock those would wait for it
            if self._open:
                with contextlib.suppress(Exception):  # darkening never raises
                    self._do_dark()
            with contextlib.suppress(Exception):
                Device.close(self)
        finally:
            if got:
                self._calls.release()
        return got

    @property
    @abc.abstractmethod
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""

    def show(self, pattern: np.ndarray) -> None:
        """Show one pattern now (streaming projectors). Goes dark if the device fails."""
        self._require_open()
        if self.mode is not ProjectorMode.STREAMING:
            raise DeviceStateError(f"{self.name}: plays preloaded sequences (load_sequence, start_sequence)")
        self._check_pattern(pattern)
        self._guarded(self._do_show, pattern)

    def show_still(self, image: np.ndarray) -> None:
        """Show one image until told otherwise, in either mode: a setup pattern to aim and focus by.
        A sequence projector leaves its sequence for a plain display where it can (a LightCrafter
        shows its video input); its next load_sequence takes it back. DeviceStateError where it
        cannot. Goes dark if the device fails."""
        self._require_open()
        self._check_pattern(image)
        self._guarded(self._do_show if self.mode is ProjectorMode.STREAMING else self._do_show_still, image)

    def _check_pattern(self, pattern: np.ndarray) -> None:
        width, height = self.resolution
        if pattern.shape != (height, width) or pattern.dtype != np.uint8:
            raise ValueError(
                f"{self.name}: pattern must be uint8 of shape {(height, width)}, got {pattern.dtype} {pattern.shape}"
            )

    def dark(self) -> None:
        """Show black. Safe to call at any time, also after a fault; never raises for a closed
        device."""
        with self._calls:
            if self._open:
                self._do_dark()

    def _guarded(self, action: Callable[..., None], *args: object) -> None:
        """Run a driver step that may light the projector: only while open (checked again under the
        lock: `shut` may have closed it meanwhile), and dark again if it fails."""
        with self._calls:
            self._require_open()
            try:
                action(*args)
            except Exception:
                with contextlib.suppress(Exception):  # the first fault is the one to report
                    self._do_dark()
                raise
            if not self._open:  # shut regardless while this call hung: what it lit goes dark
                with contextlib.suppress(Exception):
                    self._do_dark()

    def load_sequence(self, sequence: PatternSequence) -> None:
        """Preload a sequence (SEQUENCE projectors). Goes dark if the device fails."""
        self._require_open()
        if self.mode is not ProjectorMode.SEQUENCE:
            raise DeviceStateError(f"{self.name}: a streaming projector shows patterns one by one (show)")
        if not sequence.entries:
            raise ValueError(f"{self.name}: a sequence needs at least one pattern")
        width, height = self.resolution
        if sequence.images is not None and any(
            i.shape != (height, width) or i.dtype != np.uint8 for i in sequence.images
        ):
            raise ValueError(f"{self.name}: sequence images must be uint8 of shape {(height, width)}")
        self._guarded(self._do_load_sequence, sequence)

    def sequence_groups(self, count: int) -> list[int]:
        """How a loaded sequence of `count` patterns plays: one start_sequence(group) per group,
        each group's patterns back to back at the sequence period, a trigger pulse each. Patterns
        past `count` (padding) are black. Most projectors play the whole sequence from one start."""
        return [count]

    def start_sequence(self, group: int = 0) -> None:
        self._require_open()
        if self.mode is not ProjectorMode.SEQUENCE:
            raise DeviceStateError(f"{self.name}: not a sequence projector")
        self._guarded(self._do_start_sequence, group)

    def stop_sequence(self) -> None:
        with self._calls:
            if self._open and self.mode is ProjectorMode.SEQUENCE:
                self._guarded(self._do_stop_sequence)

    @abc.abstractmethod
    def _do_show(self, pattern: np.ndarray) -> None: ...

    @abc.abstractmethod
    def _do_dark(self) -> None: ...

    def _do_show_still(self, image: np.ndarray) -> None:
        raise DeviceStateError(f"{self.name}: plays preloaded sequences only; it cannot show a still image")

    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        raise DeviceStateError(f"{self.name}: sequences are not supported")

    def _do_start_sequence(self, group: int = 0) -> None:
        raise DeviceStateError(f"{self.name}: sequences are not supported")

    def _do_stop_sequence(self) -> None:
        raise DeviceStateError(f"{self.name}: sequences are not supported")

    def _do_close(self) -> None:
        self._do_dark()


class Camera(Device):
    """A camera captures frames with a monotonic timestamp and a sequence number."""

    @property
    @abc.abstractmethod
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""

    trigger: TriggerMode = TriggerMode.INTERNAL

    def set_trigger(self, mode: TriggerMode) -> None:
        """INTERNAL: free-running, capture() takes the next frame; EXTERNAL: one exposure per pulse
        on the trigger input (a projector's trigger out)."""
        self._require_open()
        if mode is TriggerMode.VSYNC:
            raise ValueError(f"{self.name}: cameras trigger internally or externally")
        self._do_set_trigger(mode)
        self.trigger = mode

    def _do_set_trigger(self, mode: TriggerMode) -> None:
        if mode is not TriggerMode.INTERNAL:
            raise DeviceStateError(f"{self.name}: this camera has no trigger input")

    _exposure_us: float = 10000.0
    has_exposure: bool = False  # the driver sets the sensor's exposure (auto-exposure and HDR need it)

    @property
    def exposure_us(self) -> float:
        return self._exposure_us

    # the manual exposures the driver can set, microseconds (the interface's bounds unless it says)
    exposure_range_us: tuple[float, float] = (1.0, 10_000_000.0)

    def set_exposure_us(self, exposure_us: float) -> None:
        """Manual exposure in microseconds, within `exposure_range_us` (ValueError naming the range
        outside it); sent to the device when it is open."""
        low, high = self.exposure_range_us
        if not low <= exposure_us <= high:
            raise ValueError(f"{self.name}: exposure_us must be in [{low:g}, {high:g}] here, got {exposure_us:g}")
        if self._open:
            self._do_set_exposure_us(float(exposure_us))
        self._exposure_us = float(exposure_us)

    def _do_set_exposure_us(self, exposure_us: float) -> None:
        """Drivers send the exposure to an open device here (default: nothing to send)."""

    _gain: float | None = None  # None: the driver leaves the sensor's gain as it is
    has_gain: bool = False  # the driver can set the sensor's analogue gain

    @property
    def gain(self) -> float | None:
        """The gain as the driver counts it (1.0 = unity where the sensor says so), or None."""
        return self._gain

    def set_gain(self, gain: float) -> None:
        """Analogue gain (0 to 64); sent to the device when it is open. DeviceStateError from a
        driver without the control, naming it."""
        if not self.has_gain:
            raise DeviceStateError(f"{self.name}: this camera's driver has no gain control")
        if not 0.0 <= gain <= 64.0:
            raise ValueError(f"{self.name}: gain must be in [0, 64], got {gain}")
        if self._open:
            self._do_set_gain(float(gain))
        self._gain = float(gain)

    def _do_set_gain(self, gain: float) -> None:
        """Drivers with has_gain send the gain to an open device here."""

    def flush(self) -> None:
        """Drop frames the driver already holds, so the next capture is exposed after this call."""
        self._require_open()
        self._do_flush()

    def _do_flush(self) -> None:
        """Drivers that buffer frames drop them here."""

    _cancel: threading.Event | None = None  # the running capture's, for _wait_until

    def capture(self, timeout_s: float = 2.0, cancel: threading.Event | None = None) -> Frame:
        """Capture one frame, taken after this call began; raise DeviceTimeoutError past
        `timeout_s`, and DeviceCancelledError once `cancel` is set (set before the call, or, for
        drivers that wait through _wait_until, while it waits)."""
        self._require_open()
        if timeout_s <= 0:
            raise ValueError(f"{self.name}: timeout_s must be > 0")
        if cancel is not None and cancel.is_set():
            raise DeviceCancelledError(f"{self.name}: capture cancelled")
        deadline = time.monotonic() + timeout_s
        self._cancel = cancel
        try:
            return self._do_capture(deadline)
        finally:
            self._cancel = None

    def _wait_until(self, deadline: float) -> None:
        """Drivers that wait for a frame in Python wait here: until `deadline` (monotonic), or
        DeviceCancelledError as soon as the capture's `cancel` is set."""
        remaining = deadline - time.monotonic()
        if self._cancel is None:
            time.sleep(max(0.0, remaining))
        elif self._cancel.wait(max(0.0, remaining)):
            raise DeviceCancelledError(f"{self.name}: capture cancelled while waiting for a frame")

    @abc.abstractmethod
    def _do_capture(self, deadline: float) -> Frame: ...


POWER_STATES = ("off", "on", "cooling", "warming")


class PowerControl(Device):
    """A projector's housekeeping channel (RS-232, PJLink): power, input selection and blanking.
    It carries no patterns; a display or LightCrafter driver does. Every call needs an open device
    and fails within the driver's timeout."""

    def power(self, on: bool) -> None:
        """Switch the lamp or light source on or off."""
        self._require_open()
        self._do_power(on)

    def power_state(self) -> str:
        """One of POWER_STATES."""
        self._require_open()
        return self._do_power_state()

    def select_input(self, name: str) -> None:
        """Select a video input by the driver's own names (serial: hdmi, hdmi2, vga; PJLink: its
        two-digit code, e.g. 31). ValueError for a name the driver does not know."""
        self._require_open()
        self._do_select_input(name)

    def blank(self, on: bool) -> None:
        """Blank (mute) the picture, or show the input again."""
        self._require_open()
        self._do_blank(on)

    @abc.abstractmethod
    def _do_power(self, on: bool) -> None: ...

    @abc.abstractmethod
    def _do_power_state(self) -> str: ...

    @abc.abstractmethod
    def _do_select_input(self, name: str) -> None: ...

    @abc.abstractmethod
    def _do_blank(self, on: bool) -> None: ...
