"""Sustained throughput of live mode's pipeline, apart from the simulator: one live sequence
(live mode's default, 4-step phase unwrapped by Gray code, 20 frames; or the shortest, cued_phase's
3 + 3 steps, 6 frames) captured once per camera on the simulated bench at each sensor size, then
fed again and again by a thread as hardware-triggered cameras at the case's rate would deliver it
(every camera's frame k at once). The pipeline is live mode's own (rig.pipeline.live,
rig.pipeline.sustained): each frame decoded as it arrives, each finished sequence triangulated on a
worker thread while the next is decoded; before the clock, two sequences of dark frames in flight
warm the heap, as live mode's start does (decisions 0042 and 0047). Two places drop whole
sequences, never frames: the camera, when its buffer already holds a whole sequence the decoder
has not read, and the worker, when a newer sequence replaces one still waiting.

Prints one JSON object {"cases": [...]}: per case clouds per second against the camera's
sequences per second, sequences dropped, latency from a sequence's last frame to its depth images
(p50, p99), CPU seconds per cloud, the bytes of a frame and of a sequence (every camera), what the
process holds before the run (the rig, the simulator, the frames it feeds) and the peak of the
sustained run above that (the warm-up's heap with it), also against the frames of two sequences
(each case in a fresh process).

    python bench/throughput.py [--docs] [--seconds 10]
    python bench/throughput.py --case 6-1280x1024-8bit-1 [--seconds 10]   # one case, its JSON alone
    python bench/throughput.py --table measured.json   # the docs' block again, from a JSON it printed

The simulator renders far slower than a camera delivers, so the rig's own capture is left out.
"""

from __future__ import annotations

import argparse
import copy
import json
import queue
import resource
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _readme import as_measured, markdown_table, replace_block
from _ring_latency import RING_CODECS, ring_latency

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.opened_rig import Rig
from rig.patterns import Codec
from rig.patterns.stream import FrameStream
from rig.pipeline.capture import capture
from rig.pipeline.live import CapturedSequence, finish_sequence, live_codecs, prepare_triangulation, warm_up
from rig.pipeline.sustained import SequenceWorker
from rig.progress import ProgressTracker
from rig.workers import release_free_memory

# The sequences: live mode's default (4-step phase unwrapped by Gray code, 20 frames on this
# projector) and the shortest, cued_phase (3 fringe steps and 3 of a single-period cue, 6 frames),
# shown as a DLP shows 8-bit patterns, light linear in the level (as_measured: 3 steps need it)
SEQUENCES: dict[str, dict[str, Any]] = {
    "20": {"codec": "phase", "params": None},
    "6": {"codec": "cued_phase", "params": {"steps": 3}},
}
SENSORS = ((1280, 1024, 120.0, (8,)), (2448, 2048, 60.0, (8, 12)), (4096, 3000, 30.0, (8,)))  # and bit depths
# name: (sequence, width, height, bit depth, cameras, rate Hz): the default bench's sensor, a 5 MP and
# a 12 MP machine-vision sensor at rates they reach over USB3 / GigE
CASES: dict[str, tuple[str, int, int, int, int, float]] = {
    f"{frames}-{width}x{height}-{bits}bit-{cameras}": (frames, width, height, bits, cameras, rate)
    for width, height, rate, depths in SENSORS
    for bits in depths
    for frames in SEQUENCES
    for cameras in (1, 2)
    if bits == 8 or (frames == "6" and cameras == 1)
}
Item = tuple[int, int, list[np.ndarray], float]  # sequence, frame index, every camera's frame, arrival


def bench_config(sequence: str, width: int, height: int, bit_depth: int, cameras: int) -> dict[str, Any]:
    """The default bench showing `sequence` in live mode, with its camera at this size (same field
    of view) and depth; a second camera on the projector's other side, as far from it as the first."""
    data = load_config().model_dump(mode="json")
    data["scan"]["live"] = SEQUENCES[sequence]
    camera = data["cameras"][0]
    scale = width / camera["resolution"][0]
    intrinsics = camera["geometry"]["intrinsics"]
    camera["resolution"] = [width, height]
    camera["bit_depth"] = bit_depth
    camera["geometry"]["intrinsics"] = {
        "fx": intrinsics["fx"] * scale,
        "fy": intrinsics["fy"] * scale,
        "cx": (width - 1) / 2,
        "cy": (height - 1) / 2,
    }
    if cameras == 2:
        second = copy.deepcopy(camera)
        second["name"] = "camera1"
        second["geometry"]["pose"]["position_mm"] = [300.0, 0.0, 600.0]
        data["cameras"].append(second)
    return data


def feed(
    frames: list[list[np.ndarray]], rate_hz: float, seconds: float, out: queue.Queue, counts: dict[str, int]
) -> None:
    """Frame k of every camera at `rate_hz`, a sequence at a time, for `seconds`; a sequence that
    would find the queue holding a whole sequence's frames is dropped whole (its frames still take
    their time, as a camera's do)."""
    period, start, sequence = 1.0 / rate_hz, time.monotonic(), 0
    while time.monotonic() - start < seconds:
        sequence += 1
        dropped = out.qsize() >= len(frames)
        counts["sequences"] += 1
        counts["dropped_by_camera"] += dropped
        for index, frame in enumerate(frames):
            due = start + ((sequence - 1) * len(frames) + index + 1) * period
            time.sleep(max(0.0, due - time.monotonic()))
            if not dropped:
                out.put((sequence, index, frame, time.perf_counter()))
    out.put(None)


class Sustained:
    """One pair per camera of the rig's first projector, fed whole sequences of frames and decoding
    as they arrive, a SequenceWorker triangulating each finished one (live mode's pipeline)."""

    def __init__(self, rig: Rig, codec: Codec, cameras: int) -> None:
        self.rig, self.codec, self.cameras = rig, codec, cameras
        self.full_scale = [camera.full_scale for camera in rig.config.cameras]
        self.latencies: list[float] = []
        self.worker: SequenceWorker[CapturedSequence, float] = SequenceWorker(
            lambda seq: finish_sequence(rig, seq).latency_ms, self.latencies.append
        )
        self._streams = self._new()
        self._first_s = 0.0

    def _new(self) -> dict[tuple[int, int], list[FrameStream]]:
        return {(0, c): [self.codec.stream(self.full_scale[c])] for c in range(self.cameras)}

    def add(self, sequence: int, index: int, frame: list[np.ndarray], arrived_s: float) -> None:
        """Frame `index` of every camera; the last one hands the sequence to the worker."""
        if index == 0:
            self._streams, self._first_s = self._new(), arrived_s
        for c in range(self.cameras):
            self._streams[(0, c)][0].add(frame[c])
        if index == self.codec.frame_count - 1:
            self.worker.submit(CapturedSequence(sequence, self._streams, self._first_s, arrived_s))


def measure_case(name: str, seconds: float) -> dict[str, Any]:
    sequence, width, height, bit_depth, cameras, rate_hz = CASES[name]
    config = config_from_dict(bench_config(sequence, width, height, bit_depth, cameras), f"throughput {name}")
    config, _ = as_measured(config, config.scan.live.codec)
    with open_rig(config) as rig:
        codecs = live_codecs(rig)
        prepare_triangulation(rig, codecs)
        captured = capture(rig, codecs, ProgressTracker(None), keep_frames=True, overlap_cue=False)
        rig.all_dark()
        frames = [[captured[(0, c)][k] for c in range(cameras)] for k in range(codecs[0].frame_count)]
        del captured
        warm = Sustained(rig, codecs[0], cameras)  # compiled and cached once, before the clock runs
        for index, frame in enumerate(frames):
            warm.add(0, index, frame, 0.0)
        warm.worker.close(60.0)
        pipeline = Sustained(rig, codecs[0], cameras)
        fixed_mb = held_from_now()
        warm_up(rig, codecs)  # as live mode starts: its heap, not the compiler's (done above)
        items: queue.Queue[Item | None] = queue.Queue()
        counts = {"sequences": 0, "dropped_by_camera": 0}
        feeder = threading.Thread(target=feed, args=(frames, rate_hz, seconds, items, counts), daemon=True)
        cpu, wall = time.process_time(), time.monotonic()
        feeder.start()
        while (item := items.get(timeout=seconds + 60)) is not None:
            pipeline.add(*item)
        pipeline.worker.close(60.0)
        wall, cpu = time.monotonic() - wall, time.process_time() - cpu
        feeder.join(60.0)
        sustained_mb = status_mb("VmHWM") - fixed_mb
    latencies, clouds, frame_bytes = pipeline.latencies, len(pipeline.latencies), frames[0][0].nbytes
    return {
        "case": name,
        "camera": f"{width}x{height} {bit_depth}-bit at {rate_hz:g} Hz",
        "cameras": cameras,
        "codec": config.scan.live.codec,
        "sequence": f"{config.scan.live.codec}, {len(frames)} frames",
        "frames_per_sequence": len(frames),
        "seconds": round(wall, 2),
        "camera_sequences_per_s": round(rate_hz / len(frames), 2),
        "clouds_per_s": round(clouds / wall, 2),
        "sequences": counts["sequences"],
        "dropped": counts["dropped_by_camera"] + pipeline.worker.dropped,
        "dropped_by_camera": counts["dropped_by_camera"],
        "dropped_by_worker": pipeline.worker.dropped,
        "latency_ms": {
            "p50": round(float(np.percentile(latencies, 50)), 1) if latencies else None,
            "p99": round(float(np.percentile(latencies, 99)), 1) if latencies else None,
        },
        "cpu_s_per_cloud": round(cpu / max(clouds, 1), 3),
        "frame_mb": round(frame_bytes / 2**20, 2),
        "sequence_mb": round(frame_bytes * len(frames) * cameras / 2**20, 1),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "fixed_mb": round(fixed_mb, 1),
        "sustained_peak_mb": round(sustained_mb, 1),
        "sustained_over_two_sequences": round(sustained_mb / (2 * frame_bytes * len(frames) * cameras / 2**20), 2),
    }


def status_mb(key: str) -> float:
    """A figure of /proc/self/status (VmRSS, VmHWM) in MB."""
    line = next(line for line in Path("/proc/self/status").read_text().splitlines() if line.startswith(key + ":"))
    return int(line.split()[1]) / 1024


def held_from_now() -> float:
    """What the process holds now (MB; the fixed overhead: the rig, the simulator, the frames fed),
    its peak reset to it (writing 5 to clear_refs), so that VmHWM later is the sustained run's."""
    release_free_memory()
    Path("/proc/self/clear_refs").write_text("5")
    return status_mb("VmRSS")


def measure_all(seconds: float) -> dict[str, Any]:
    cases, rings = [], []
    for name in (*CASES, *RING_CODECS):  # each in a fresh process: its own peak memory
        command = [sys.executable, __file__, "--case", name, "--seconds", str(seconds)]
        done = subprocess.run(command, capture_output=True, text=True, timeout=1800)
        if done.returncode:
            raise SystemExit(f"throughput case {name} failed:\n{done.stderr[-3000:]}")
        (rings if name in RING_CODECS else cases).append(json.loads(done.stdout.strip().splitlines()[-1]))
    return {"benchmark": "throughput", "cases": cases, "ring_codecs": rings}


def table(measured: dict[str, Any]) -> str:
    header = ["sequence", "camera", "cameras", "camera sequences/s", "clouds/s", "dropped", "latency p50 / p99 ms"]
    header += ["CPU s per cloud", "frame MB", "sequence MB", "held before MB", "sustained peak above it MB"]
    header.append("that / two sequences")
    rows = [
        [
            f"{as_measured(load_config(), c['sequence'].split(',')[0])[1]}, {c['frames_per_sequence']} frames",
            c["camera"],
            c["cameras"],
            c["camera_sequences_per_s"],
            c["clouds_per_s"],
            f"{c['dropped']} of {c['sequences']}",
            f"{c['latency_ms']['p50']} / {c['latency_ms']['p99']}",
            c["cpu_s_per_cloud"],
            c["frame_mb"],
            c["sequence_mb"],
            c["fixed_mb"],
            c["sustained_peak_mb"],
            c["sustained_over_two_sequences"],
        ]
        for c in measured["cases"]
    ]
    text = markdown_table(header, rows)
    if measured.get("ring_codecs"):
        ring_header = ["codec (default bench, 120 Hz)", "frames", "points", "last frame to points ms (worst)"]
        ring_header += ["to the organised cloud ms (worst)", "to the surface and colour ms (worst)"]
        text += "\n\n" + markdown_table(ring_header, [_ring_row(r) for r in measured["ring_codecs"]])
    return text + "\n\nProduced by `python bench/throughput.py --docs`."


def _ring_row(r: dict[str, Any]) -> list[object]:
    surface = "no surface"
    if "last_frame_to_surface_ms" in r:
        surface = f"{r['last_frame_to_surface_ms']} ({r['last_frame_to_surface_ms_worst']})"
    points = f"{r['last_frame_to_points_ms']} ({r['last_frame_to_points_ms_worst']})"
    cloud = "no organised cloud"
    if "last_frame_to_cloud_ms" in r:
        cloud = f"{r['last_frame_to_cloud_ms']} ({r['last_frame_to_cloud_ms_worst']})"
    return [r["codec"], r["frames"], r["points"], points, cloud, surface]


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--case", choices=sorted([*CASES, *RING_CODECS]), help="measure this case alone, here")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long the cameras deliver, per case")
    parser.add_argument("--docs", action="store_true", help="rewrite the throughput block of docs/results.md")
    parser.add_argument("--table", type=Path, help="rewrite the block from this JSON, which the bench printed before")
    args = parser.parse_args()
    if args.table:
        replace_block("throughput-table", table(json.loads(args.table.read_text())))
        return
    if args.case:
        case = args.case
        print(json.dumps(ring_latency(case) if case in RING_CODECS else measure_case(case, args.seconds)))
        return
    measured = measure_all(args.seconds)
    print(json.dumps(measured))
    if args.docs:
        replace_block("throughput-table", table(measured))


if __name__ == "__main__":
    main()
