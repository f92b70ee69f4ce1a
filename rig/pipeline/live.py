"""Live mode: the rig repeats a short sequence (scan.live: 4-step phase by default) and hands on a
depth image per camera for every sequence, as fast as projector and cameras allow.

Each sequence is decoded while it is captured (rig.patterns.stream) and triangulated by the
organised fast path where the pair allows it, on a worker thread while the next sequence is
captured (rig.pipeline.sustained), so a sequence's depth images are ready a few milliseconds after
its last frame and the rig does not wait for them. When triangulating falls behind, sequences are
dropped whole and counted. Nothing is stored. Whoever watches takes the newest frame (`publish`
must not block): a slow reader skips sequences and never slows the rig.
"""

from __future__ import annotations

import logging
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rig.config import ScanConfig
from rig.errors import DecodeError, ScanError
from rig.opened_rig import Rig
from rig.patterns import Codec, Correspondence, FrameStream
from rig.pipeline.capture import capture
from rig.pipeline.exposure import ExposureSettings, require_exposure, set_within_range, settled_exposures
from rig.pipeline.hdr import bracketed
from rig.pipeline.organised import fast_terms, organised_depth
from rig.pipeline.pass_merge import merge_exposures
from rig.pipeline.scan import is_reconstructed, make_codec, organised_terms, reconstruct_pair, triangulator
from rig.pipeline.sustained import SequenceWorker
from rig.progress import ProgressTracker

FINISH_TIMEOUT_S = 60.0  # the last sequence's triangulation, once live mode stops
log = logging.getLogger(__name__)
LATENCIES_KEPT = 256  # the summary's latency figures are over the last this many sequences
RATE_OVER = 32  # clouds per second: over the last this many sequences
WARM_UP_SEQUENCES = 2  # one decoded while the one before is triangulated


@dataclass(frozen=True, eq=False)
class LiveFrame:
    """One live sequence's result."""

    sequence: int  # counts up from 1 over a live session
    depths: tuple[np.ndarray, ...]  # per camera: (H, W) float32 mm along its axis, NaN where no point
    points: int  # points over every pair
    latency_ms: float  # from the sequence's last frame arriving to its depth images ready
    sequence_ms: float  # from its first pattern to its depth images ready
    ready_s: float  # time.monotonic() when ready


@dataclass
class LiveStats:
    """Running figures of a live session: clouds per second and latency."""

    started_s: float = field(default_factory=time.monotonic)  # reset when the first sequence starts
    last_ready_s: float | None = None
    sequences: int = 0  # the newest published sequence's number
    captured: int = 0  # sequences captured (numbered from 1)
    dropped: int = 0  # sequences captured but not triangulated: the machine fell behind
    points: int = 0
    latencies_ms: deque[float] = field(default_factory=lambda: deque(maxlen=LATENCIES_KEPT))
    ready_s: deque[float] = field(default_factory=lambda: deque(maxlen=RATE_OVER))
    sequence_ms: deque[float] = field(default_factory=lambda: deque(maxlen=LATENCIES_KEPT))
    # the sequence worker adds while the daemon's handlers read: each holds this
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def add(self, frame: LiveFrame) -> None:
        with self.lock:
            self.sequences = frame.sequence
            self.last_ready_s = frame.ready_s
            self.ready_s.append(frame.ready_s)
            self.points = frame.points
            self.latencies_ms.append(frame.latency_ms)
            self.sequence_ms.append(frame.sequence_ms)

    def recent_rate(self) -> float:
        """Sequences per second over the last RATE_OVER (from the first sequence's start while
        there is only one)."""
        ready = list(self.ready_s)  # a copy: the worker may be adding
        if len(ready) >= 2:
            return (len(ready) - 1) / max(ready[-1] - ready[0], 1e-9)
        elapsed = (self.last_ready_s or self.started_s) - self.started_s
        return self.sequences / elapsed if elapsed > 0 else 0.0

    def as_dict(self) -> dict[str, object]:
        with self.lock:
            return self._figures()

    def _figures(self) -> dict[str, object]:
        seconds = (self.last_ready_s or self.started_s) - self.started_s
        latencies = sorted(self.latencies_ms)
        return {
            "sequences": self.sequences,
            "dropped": self.dropped,
            "seconds": round(seconds, 3),
            "clouds_per_s": round(self.recent_rate(), 3),
            "latency_ms": None
            if not latencies
            else {
                "median": round(statistics.median(latencies), 2),
                "p95": round(latencies[min(len(latencies) - 1, int(0.95 * len(latencies)))], 2),
                "max": round(latencies[-1], 2),
            },
            "sequence_ms_median": round(statistics.median(self.sequence_ms), 1) if self.sequence_ms else None,
            "points": self.points,
        }


def live_codecs(rig: Rig, scan: ScanConfig | None = None) -> list[Codec]:
    """One codec per projector: `scan.live`'s codec with its parameters (default: the rig's config)."""
    scan = scan or rig.config.scan
    params = scan.live_params()
    return [make_codec(rig, p, scan.live.codec, params) for p in range(len(rig.projectors))]


def run_live(
    rig: Rig,
    publish: Callable[[LiveFrame], None],
    keep_going: Callable[[], bool],
    stats: LiveStats | None = None,
    scan: ScanConfig | None = None,
) -> LiveStats:
    """Repeat the live sequence of `scan.live` (default: the rig's config) while `keep_going()`
    (asked before each one), handing each result to `publish`; projectors dark at the end,
    however it ends."""
    codecs = live_codecs(rig, scan)
    prepare_triangulation(rig, codecs)
    warm_up(rig, codecs)
    exposures = live_exposures(rig, (scan or rig.config.scan).live.hdr)
    stats = stats if stats is not None else LiveStats()
    if stats.sequences == 0:
        stats.started_s = time.monotonic()  # the rate counts sequences, not the preparation

    def published(frame: LiveFrame) -> None:
        stats.add(frame)
        publish(frame)

    worker: SequenceWorker[CapturedSequence, LiveFrame] = SequenceWorker(
        lambda captured: finish_sequence(rig, captured), published
    )
    dropped, ended = stats.dropped, False
    try:
        while keep_going():
            captured = capture_sequence(rig, codecs, stats.captured + 1, exposures)
            stats.captured += 1
            worker.submit(captured)
            stats.dropped = dropped + worker.dropped
        ended = True
    finally:
        try:
            rig.all_dark()
        finally:
            _close(worker, raise_failure=ended)
            stats.dropped = dropped + worker.dropped
    return stats


def _close(worker: SequenceWorker, raise_failure: bool) -> None:
    """Finish the sequence still waiting; where live mode is already failing, a failure of the
    worker's is logged, not raised in place of the one that ended it."""
    try:
        worker.close(FINISH_TIMEOUT_S)
    except Exception:
        if raise_failure:
            raise
        log.exception("live mode: the last sequence failed too")


def live_exposures(rig: Rig, hdr: str | list[float] | None) -> list[list[float]] | None:
    """Each camera's exposures for every live sequence (scan.live.hdr): None for the cameras' own;
    "auto" bracketed once now, from auto-exposure's pre-captures."""
    if hdr is None:
        return None
    for camera in rig.cameras:
        require_exposure(camera, "live HDR")
    settings = ExposureSettings()
    looks = settled_exposures(rig, settings)[0] if hdr == "auto" else None
    return bracketed(rig, hdr, looks, settings)


@dataclass(frozen=True, eq=False)
class CapturedSequence:
    """A sequence whose frames are all in, decoded as they arrived: what finish_sequence needs."""

    sequence: int
    streams: dict[tuple[int, int], list[FrameStream]]  # per pair, one per exposure
    started_s: float  # time.perf_counter() at its first pattern
    last_frame_s: float  # ... when its last frame arrived


def capture_sequence(
    rig: Rig, codecs: list[Codec], sequence: int, exposures: list[list[float]] | None = None
) -> CapturedSequence:
    """Show the sequence once (at each of the cameras' `exposures`, where given), decoding every
    pair's frames as they arrive."""
    full_scale = [camera.full_scale for camera in rig.config.cameras]
    pairs = [(p, c) for p in range(len(codecs)) for c in range(len(rig.cameras)) if is_reconstructed(rig, (p, c))]
    passes: dict[tuple[int, int], list[FrameStream]] = {pair: [] for pair in pairs}
    arrived = [0.0]
    start = time.perf_counter()
    for k in range(1 if exposures is None else len(exposures[0])):
        if exposures is not None:
            set_within_range(rig.cameras, [e[k] for e in exposures])
        streams = {(p, c): codecs[p].stream(full_scale[c]) for p, c in pairs}

        def decode_now(p: int, c: int, image: np.ndarray, streams: dict = streams) -> None:
            arrived[0] = time.perf_counter()
            if (p, c) in streams:
                streams[(p, c)].add(image)

        capture(rig, codecs, ProgressTracker(None), decode_now, keep_frames=False, overlap_cue=False)
        for pair, stream in streams.items():
            passes[pair].append(stream)
    return CapturedSequence(sequence, passes, start, arrived[0])


def finish_sequence(rig: Rig, captured: CapturedSequence) -> LiveFrame:
    """Finish each pair's decode (merged per pixel over the exposures) and triangulate it."""
    depths: dict[int, np.ndarray] = {}
    points = 0
    for (p, c), streams in captured.streams.items():
        try:
            corrs = [stream.finish() for stream in streams]
        except DecodeError as exc:
            raise ScanError(f"{rig.config.cameras[c].name}: {exc}") from exc
        corr = corrs[0] if len(corrs) == 1 else merge_exposures(corrs, len(corrs) - 1)
        depth, found = pair_depth(rig, p, c, corr)
        points += found
        depths.setdefault(c, depth)  # a camera's depth image: from the first projector that lights it
    ready = time.perf_counter()
    return LiveFrame(
        sequence=captured.sequence,
        depths=tuple(depths[c] if c in depths else _no_depth(rig, c) for c in range(len(rig.cameras))),
        points=points,
        latency_ms=(ready - captured.last_frame_s) * 1e3,
        sequence_ms=(ready - captured.started_s) * 1e3,
        ready_s=time.monotonic(),
    )


def _no_depth(rig: Rig, camera: int) -> np.ndarray:
    """The depth image of a camera no pair reconstructs: no point anywhere."""
    width, height = rig.config.cameras[camera].resolution
    return np.full((height, width), np.nan, np.float32)


def prepare_triangulation(rig: Rig, codecs: list[Codec]) -> None:
    """Compute each pair's per-pixel triangulation terms now, so the first sequence is as quick as
    the others."""
    for p, codec in enumerate(codecs):
        for c in range(len(rig.cameras)):
            if codec.coded_axes() and is_reconstructed(rig, (p, c)):
                fast_terms(triangulator(rig, p, c), codec.coded_axes())


def warm_up(rig: Rig, codecs: list[Codec]) -> int:
    """Two sequences of dark frames through every pair's decode and triangulation, their results
    dropped: the heap then holds what the sequences in flight need before the cameras run. Started
    cold (an idle daemon hands its free memory back after each job), the first sequences of two
    5 MP cameras took three to four times as long as the rest while their arrays were faulted in,
    and one was dropped (decision 0042). One sequence warmed was not enough: while one sequence is
    triangulated the next is decoded, so two sequences' arrays are live at once, and the heap went on
    growing over the first several sequences, which dropped one to three sequences in every run
    measured (decision 0047).
    How many pairs went all the way (a pair whose dark frames do not decode is logged and passed
    over: what it allocated on the way is in the heap too)."""
    cameras, dark = rig.config.cameras, dark_frames(rig)
    pairs = [(p, c) for p in range(len(codecs)) for c in range(len(cameras)) if is_reconstructed(rig, (p, c))]
    in_flight = []
    for _ in range(WARM_UP_SEQUENCES):  # every pair's frames in, as a sequence's are, both held
        streams = {(p, c): codecs[p].stream(cameras[c].full_scale) for p, c in pairs}
        for (p, c), stream in streams.items():
            for _ in range(codecs[p].frame_count):
                stream.add(dark[c])
        in_flight.append(streams)
    warmed = {pair: True for pair in pairs}
    for streams in in_flight:
        for (p, c), stream in streams.items():
            try:
                pair_depth(rig, p, c, stream.finish())
            except (DecodeError, ScanError) as exc:
                if warmed[(p, c)]:  # said once, not once a sequence
                    log.info("live mode warm-up: projector %d, camera %s: %s", p, cameras[c].name, exc)
                warmed[(p, c)] = False
    return sum(warmed.values())


def dark_frames(rig: Rig) -> list[np.ndarray]:
    """Per camera, a dark frame of the shape and type it delivers (BGR for a colour sensor, 16 bits
    a sample beyond 8)."""
    shapes = [(c.resolution[1], c.resolution[0], *((3,) if c.color else ())) for c in rig.config.cameras]
    return [
        np.zeros(shape, np.uint8 if c.bit_depth == 8 else np.uint16)
        for shape, c in zip(shapes, rig.config.cameras, strict=True)
    ]


def pair_depth(rig: Rig, projector: int, camera: int, corr: Correspondence) -> tuple[np.ndarray, int]:
    """The pair's depth image and the points it has: the organised fast path's depth alone, or the
    general triangulation where the pair needs it."""
    fast = organised_terms(rig, projector, camera, corr)
    if fast is not None:
        return organised_depth(fast, corr, rig.config.scan.max_depth_jump_mm)
    model = rig.camera_models[camera]
    grid = reconstruct_pair(rig, projector, camera, corr, source=0).grid
    depth = ((grid - model.center) @ model.axis).astype(np.float32)
    return depth, int(np.isfinite(depth).sum())
