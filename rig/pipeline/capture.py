"""Capture: every pattern of every projector, seen by every camera, in sync.

Streaming projectors use software sync (show, wait the measured latency, drop frames exposed
before it, capture); sequence projectors use hardware sync (the projector plays the sequence and its
trigger output starts each camera exposure; frames are matched to patterns by sequence number and
timestamp). A device fault darkens every projector and fails the scan.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable

import numpy as np

from drivers.base import Frame, ProjectorMode
from drivers.errors import DeviceError
from drivers.sequences import PatternSequence, SequenceEntry, TriggerMode
from rig.errors import CaptureFaultError, ScanError
from rig.opened_rig import Rig
from rig.patterns import Codec, sent_levels
from rig.progress import ProgressTracker

Frames = dict[tuple[int, int], list[np.ndarray]]
FrameSink = Callable[[int, int, np.ndarray], None]  # (projector, camera, image)

log = logging.getLogger(__name__)
STAMP_TOLERANCE_S = 0.0005  # V4L2 stamps reach us in milliseconds
MAX_EARLY_FRAMES = 8  # frames exposed before the light that one capture may discard
CLOCKS_APART_S = 5.0  # a frame this far before the light is on another clock: stamps cannot gate


class _Progress:
    def __init__(self, tracker: ProgressTracker, total: int) -> None:
        self.tracker, self.total, self.done = tracker, total, 0

    def step(self) -> None:
        self.done += 1
        self.tracker.report("capture", 0.6 * self.done / self.total)


def capture(
    rig: Rig,
    codecs: list[Codec],
    tracker: ProgressTracker,
    on_frame: FrameSink | None = None,
    keep_frames: bool = True,
    overlap_cue: bool = True,
) -> Frames:
    """Frames per (projector, camera); every projector is dark while another one projects.
    `on_frame(projector, camera, image)` is called with each coded frame as it arrives (decoding
    while capturing: rig.patterns.stream). Without `keep_frames` the coded frames are only handed
    on (their lists stay empty: a scan then holds one frame at a time); the overlap cue's frames,
    taken where the rig wants them and `overlap_cue` allows, are always kept."""
    progress = _Progress(tracker, sum(c.frame_count for c in codecs))
    frames: Frames = {}

    def deliver(p: int, c: int, image: np.ndarray) -> None:
        if keep_frames:
            frames[(p, c)].append(image)
        if on_frame is not None:
            on_frame(p, c, image)

    last_sequence = [-1] * len(rig.cameras)  # across projectors: a frame repeated at a switch is stale too
    try:
        rig.all_dark()
        for p, (projector, codec) in enumerate(zip(rig.projectors, codecs, strict=True)):
            for c in range(len(rig.cameras)):
                frames[(p, c)] = []
            if projector.mode is ProjectorMode.SEQUENCE:
                _capture_sequence(rig, p, codec.patterns(), deliver, last_sequence, progress)
            else:
                _capture_streaming(rig, p, codec.iter_patterns(), deliver, last_sequence, progress)
            projector.dark()
        if overlap_cue and wants_overlap_cue(rig):
            _capture_overlap_cue(rig, frames, last_sequence)
    except DeviceError as exc:
        rig.all_dark()
        raise ScanError(f"capture failed: {exc}") from exc
    except BaseException:
        rig.all_dark()
        raise
    return frames


CUE = -1  # frames[(CUE, camera)]: dark, each projector white alone, all white together


def wants_overlap_cue(rig: Rig) -> bool:
    merge = rig.config.scan.merge
    return (
        len(rig.projectors) > 1
        and merge.enabled
        and merge.overlap_cue
        and all(p.mode is ProjectorMode.STREAMING for p in rig.projectors)
    )


def _capture_overlap_cue(rig: Rig, frames: Frames, last_sequence: list[int]) -> None:
    """The dissertation's intensity cue: where several projectors light a surface it is brighter
    than any one of them makes it. Frames: all dark, each projector alone, all together."""
    steps: list[list[int]] = [[], *([p] for p in range(len(rig.projectors))), list(range(len(rig.projectors)))]
    for c, stills in lit_stills(rig, steps, last_sequence).items():
        frames[(CUE, c)] = stills


def lit_stills(rig: Rig, steps: list[list[int]], last_sequence: list[int] | None = None) -> dict[int, list[np.ndarray]]:
    """Per camera, a frame for each step of `steps` (the projectors lit white in it, the others
    dark), each exposed once its light was on; every projector dark after."""
    timeout = rig.config.scan.capture_timeout_s
    latency = max(rig.latency_s(p) for p in range(len(rig.projectors)))
    last = [-1] * len(rig.cameras) if last_sequence is None else last_sequence
    white = [white_image(rig, p) for p in range(len(rig.projectors))]
    stills: dict[int, list[np.ndarray]] = {c: [] for c in range(len(rig.cameras))}
    try:
        for lit in steps:
            presented: list[float] = []
            for p, projector in enumerate(rig.projectors):
                if p in lit:
                    projector.show(white[p])
                    if projector.last_present_s is not None:
                        presented.append(projector.last_present_s)
                else:
                    projector.dark()
            lit_from = max(presented) + latency if len(presented) == len(lit) and lit else None
            rig.wait(latency)
            for camera in rig.cameras:
                camera.flush()
            for c in stills:
                stills[c].append(_take_lit(rig, c, timeout, last, lit_from).image)
    finally:
        rig.all_dark()
    return stills


def white_image(rig: Rig, p: int) -> np.ndarray:
    """Projector `p` all white: full, or as its intensity mask dims it (adaptive projection)."""
    width, height = rig.projectors[p].resolution
    white = np.full((height, width), 255, np.uint8)
    if not rig.intensity_masks:
        return white
    return sent_levels(white, rig.intensity_masks[p], rig.response_luts[p] if rig.response_luts else None)


def _take(rig: Rig, c: int, timeout_s: float, last_sequence: list[int]) -> Frame:
    camera = rig.cameras[c]
    frame = rig.capture(c, timeout_s)  # its wait cut short by a cancel
    if frame.sequence <= last_sequence[c]:
        raise CaptureFaultError(f"{camera.name}: stale frame (sequence {frame.sequence})")
    last_sequence[c] = frame.sequence
    return frame


def _take_lit(rig: Rig, c: int, timeout_s: float, last_sequence: list[int], lit_from: float | None) -> Frame:
    """The first frame whose exposure began once the pattern was lit. A flush cannot drop the frame
    being exposed while it runs, and a driver may hold more frames than it says; stamps tell."""
    for _ in range(MAX_EARLY_FRAMES + 1):
        frame = _take(rig, c, timeout_s, last_sequence)
        if lit_from is None or frame.exposure_start_s >= lit_from - STAMP_TOLERANCE_S:
            return frame
        if lit_from - frame.exposure_start_s > CLOCKS_APART_S:
            log.warning("%s: frame stamps are not on the projector's clock; cannot gate by time", rig.cameras[c].name)
            return frame
        log.debug("%s: frame %d exposed before the light, dropped", rig.cameras[c].name, frame.sequence)
    raise CaptureFaultError(
        f"{rig.cameras[c].name}: {MAX_EARLY_FRAMES + 1} frames in a row were exposed before the pattern was lit"
    )


def _capture_streaming(
    rig: Rig, p: int, patterns: Iterable[np.ndarray], deliver: FrameSink, last_sequence: list[int], progress: _Progress
) -> None:
    """Show each pattern and take each camera's first frame lit by it; a pattern is made as its turn
    comes (Codec.iter_patterns), so only what the projector keeps of those shown is held."""
    projector = rig.projectors[p]
    latency = rig.latency_s(p)
    timeout = rig.config.scan.capture_timeout_s
    for pattern in patterns:
        projector.show(pattern)
        presented = projector.last_present_s
        lit_from = None if presented is None else presented + latency
        rig.wait(latency)  # until the light is on the scene
        for camera in rig.cameras:
            camera.flush()  # frames exposed before that are the previous pattern
        for c in range(len(rig.cameras)):
            deliver(p, c, _take_lit(rig, c, timeout, last_sequence, lit_from).image)
        progress.step()


def _check_follows(name: str, before: Frame | None, frame: Frame, period_s: float) -> None:
    """Within a group, frames follow one another one pattern period apart."""
    if before is None:
        return
    gap = frame.timestamp_s - before.timestamp_s
    if frame.sequence != before.sequence + 1:
        raise CaptureFaultError(f"{name}: dropped frames during the sequence")
    if abs(gap - period_s) > 0.5 * period_s:
        raise CaptureFaultError(
            f"{name}: a trigger was missed ({gap:.4f} s between frames, pattern period {period_s:.4f} s)"
        )


def _capture_sequence(
    rig: Rig, p: int, patterns: list[np.ndarray], deliver: FrameSink, last_sequence: list[int], progress: _Progress
) -> None:
    """Frame k belongs to pattern k: sequence numbers must follow one another and timestamps be one
    pattern period apart, or a trigger was missed and the scan fails."""
    projector = rig.projectors[p]
    config = rig.config.projectors[p]
    period_s = config.pattern_period_us * 1e-6
    timeout = rig.config.scan.capture_timeout_s + rig.latency_s(p) + period_s
    sequence = PatternSequence(
        entries=tuple(SequenceEntry(k % 3, 8) for k in range(len(patterns))),  # 8-bit: 3 per video frame
        exposure_us=config.pattern_period_us,
        period_us=config.pattern_period_us,
        trigger=TriggerMode.INTERNAL,
        images=tuple(patterns),
    )
    for camera in rig.cameras:
        camera.set_trigger(TriggerMode.EXTERNAL)
    try:
        projector.load_sequence(sequence)
        taken = 0
        for group, count in enumerate(projector.sequence_groups(len(patterns))):
            projector.start_sequence(group)
            previous: list[Frame | None] = [None] * len(rig.cameras)
            for _ in range(count):
                for c in range(len(rig.cameras)):
                    frame = _take(rig, c, timeout, last_sequence)
                    _check_follows(rig.cameras[c].name, previous[c], frame, period_s)
                    previous[c] = frame
                    if taken < len(patterns):  # later ones are the projector's padding
                        deliver(p, c, frame.image)
                if taken < len(patterns):
                    progress.step()
                taken += 1
    finally:
        projector.stop_sequence()
        for camera in rig.cameras:
            camera.set_trigger(TriggerMode.INTERNAL)
