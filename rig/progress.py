"""Progress events of a scan: the CLI draws them as a bar, the API streams them."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TextIO


@dataclass(frozen=True)
class ProgressEvent:
    stage: str  # capture, decode, triangulate, merge, store
    fraction: float  # of the whole scan, 0..1
    elapsed_s: float
    remaining_s: float | None
    message: str = ""

    def as_dict(self) -> dict[str, object]:
        """As the API's progress events carry it."""
        remaining = None if self.remaining_s is None else round(self.remaining_s, 3)
        return {
            "stage": self.stage,
            "fraction": self.fraction,
            "elapsed_s": round(self.elapsed_s, 3),
            "remaining_s": remaining,
        }


ProgressCallback = Callable[[ProgressEvent], None]


class ProgressTracker:
    """Turns (stage, fraction) reports into events with elapsed and estimated remaining time."""

    def __init__(self, callback: ProgressCallback | None) -> None:
        self._callback = callback
        self._start = time.monotonic()

    def report(self, stage: str, fraction: float, message: str = "") -> None:
        if self._callback is None:
            return
        elapsed = time.monotonic() - self._start
        remaining = elapsed * (1 - fraction) / fraction if fraction > 0.02 else None
        self._callback(ProgressEvent(stage, round(min(1.0, fraction), 6), elapsed, remaining, message))


class TerminalBar:
    """A one-line progress bar on a terminal stream (for use as a ProgressCallback)."""

    def __init__(self, stream: TextIO = sys.stderr, width: int = 30) -> None:
        self._stream = stream
        self._width = width

    def __call__(self, event: ProgressEvent) -> None:
        filled = round(event.fraction * self._width)
        eta = f" ~{event.remaining_s:.0f}s left" if event.remaining_s is not None else ""
        line = f"\r[{'#' * filled}{'.' * (self._width - filled)}] {event.fraction * 100:5.1f}% {event.stage:<11}{eta}"
        self._stream.write(line.ljust(72))
        if event.fraction >= 1.0:
            self._stream.write("\n")
        self._stream.flush()
