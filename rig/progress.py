"""Progress events of a long step (a scan, a calibration, a plan): the CLI draws them as a bar on a
terminal and as plain lines elsewhere, the API streams them."""

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

    def part(self, start: float, end: float, prefix: str = "") -> ProgressCallback | None:
        """A step's own progress (0..1) reported through this tracker as [start, end] of the whole,
        its stages named with `prefix` ('pilot ' + 'capture')."""
        if self._callback is None:
            return None
        span = end - start
        return lambda event: self.report(prefix + event.stage, start + span * event.fraction, event.message)


def human_seconds(seconds: float) -> str:
    """3.8 s, 42 s, 2 min 5 s: as a person reads a duration."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 90:
        return f"{seconds:.0f} s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest} s"


class TerminalBar:
    """A one-line progress bar on a terminal stream (for use as a ProgressCallback), redrawn in place."""

    def __init__(self, stream: TextIO = sys.stderr, width: int = 24) -> None:
        self._stream = stream
        self._width = width

    def __call__(self, event: ProgressEvent) -> None:
        filled = round(event.fraction * self._width)
        left = f", ~{human_seconds(event.remaining_s)} left" if event.remaining_s is not None else ""
        about = f" {event.message}" if event.message else ""
        line = (
            f"\r[{'#' * filled}{'.' * (self._width - filled)}] {event.fraction * 100:3.0f} % {event.stage}{about} "
            f"({human_seconds(event.elapsed_s)}{left})"
        )
        self._stream.write(line[:119].ljust(80))
        if event.fraction >= 1.0:
            self._stream.write("\n")
        self._stream.flush()


class StageLines:
    """Progress as plain lines, one per stage (for a log or a pipe, where a redrawn bar is noise)."""

    def __init__(self, stream: TextIO = sys.stderr) -> None:
        self._stream = stream
        self._stage = ""

    def __call__(self, event: ProgressEvent) -> None:
        if event.stage == self._stage and event.fraction < 1.0:
            return
        self._stage = event.stage
        about = f": {event.message}" if event.message else ""
        self._stream.write(f"{event.stage}{about} ({human_seconds(event.elapsed_s)})\n")
        self._stream.flush()
