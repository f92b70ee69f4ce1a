"""The newest camera frame of each camera, whoever captured it (aim mode, live mode, a scan), for
the console's camera views.

The rig's capture hands every frame here (Rig.tap): a reference is kept, nothing is copied or
encoded on the worker's thread. Readers wait for a frame newer than the one they have, so a slow
reader gets fewer frames and never a queue, and no reader ever holds up the rig.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from dataclasses import dataclass

from drivers.base import Frame


@dataclass(frozen=True)
class TappedFrame:
    """A frame, the tap's count for it (rising across rigs and sessions) and when it arrived."""

    count: int
    frame: Frame
    arrived_s: float  # time.monotonic()


class FrameTap:
    """Newest frame per camera index; thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._count = 0
        self._frames: dict[int, TappedFrame] = {}
        self._arrivals: dict[int, list[float]] = {}
        self._watchers: list[tuple[asyncio.AbstractEventLoop, asyncio.Event]] = []

    def publish(self, camera: int, frame: Frame) -> None:
        now = time.monotonic()
        with self._lock:
            self._count += 1
            self._frames[camera] = TappedFrame(self._count, frame, now)
            recent = self._arrivals.setdefault(camera, [])
            recent.append(now)
            del recent[: max(0, len(recent) - 30)]
            woken, self._watchers = self._watchers, []
        for loop, event in woken:  # readers on an event loop: woken there, never polled
            with contextlib.suppress(RuntimeError):  # a loop that has closed
                loop.call_soon_threadsafe(event.set)

    async def next_after(self, camera: int, after: int, timeout_s: float) -> TappedFrame | None:
        """The newest frame of `camera` once its count is above `after`, or None after `timeout_s`;
        the reader waits on its event loop, woken by publish, and holds no thread meanwhile."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        while True:
            event = asyncio.Event()
            left = deadline - loop.time()
            with self._lock:
                found = self._frames.get(camera)
                if found is not None and found.count > after:
                    return found
                if left <= 0:
                    return None
                self._watchers.append((loop, event))
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(event.wait(), left)

    def newest(self, camera: int) -> TappedFrame | None:
        with self._lock:
            return self._frames.get(camera)

    def rate(self, camera: int) -> float:
        """Frames per second that reached the tap from `camera` over its last (up to) 30 frames,
        0 when none arrived in the last 2 s."""
        with self._lock:
            recent = list(self._arrivals.get(camera, []))
        if len(recent) < 2 or time.monotonic() - recent[-1] > 2.0:
            return 0.0
        return (len(recent) - 1) / max(1e-6, recent[-1] - recent[0])
