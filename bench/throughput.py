"""Sustained throughput of live mode's pipeline, apart from the simulator: one live sequence of the
default bench (1280x1024, live mode's codec: 4-step phase unwrapped by Gray code) captured once,
then fed again and again by a thread as a camera at `--rate` Hz would deliver it, while the
pipeline decodes each frame as it arrives and triangulates each finished sequence, as
`rig.pipeline.live.live_sequence` does. A sequence that finds the queue still holding the last
whole sequence is dropped whole (never frames mixed across sequences) and counted. Prints one JSON
object: clouds per second, the camera's sequences per second, dropped sequences, latency from a
sequence's last frame to its depth image (p50, p99), and CPU seconds per cloud.

    python bench/throughput.py [--rate 120] [--seconds 10]

A baseline for issue 43: the pipeline is sequential today (decode while the frames arrive, then
triangulate before the next sequence is read), and the rig's own capture is left out (the
simulator renders far slower than a camera delivers).
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rig.assembly import open_rig
from rig.config import load_config
from rig.pipeline.capture import capture
from rig.pipeline.live import live_codecs, pair_depth, prepare_triangulation
from rig.progress import ProgressTracker

Item = tuple[int, int, np.ndarray, float]  # sequence, frame index, frame, when it arrived


def feed(frames: list[np.ndarray], rate_hz: float, seconds: float, out: queue.Queue, counts: dict[str, int]) -> None:
    """Frames at `rate_hz` for `seconds`, a sequence at a time; a sequence that would find the queue
    holding more than one sequence's frames is dropped whole (the camera's frames still take their
    time)."""
    period, start, sequence = 1.0 / rate_hz, time.monotonic(), 0
    while time.monotonic() - start < seconds:
        sequence += 1
        dropped = out.qsize() > len(frames)  # the pipeline still has a whole sequence to read
        counts["sequences"] += 1
        counts["dropped"] += dropped
        for index, frame in enumerate(frames):
            due = start + ((sequence - 1) * len(frames) + index + 1) * period
            time.sleep(max(0.0, due - time.monotonic()))
            if not dropped:
                out.put((sequence, index, frame, time.monotonic()))
    out.put(None)


def measure(rate_hz: float, seconds: float) -> dict[str, Any]:
    config = load_config()
    with open_rig(config) as rig:
        codecs = live_codecs(rig)
        prepare_triangulation(rig, codecs)
        frames = capture(rig, codecs, ProgressTracker(None), keep_frames=True, overlap_cue=False)[(0, 0)]
        rig.all_dark()
        full_scale = config.cameras[0].full_scale
        warm = codecs[0].stream(full_scale)  # compiled and cached once, before the clock runs
        for frame in frames:
            warm.add(frame)
        pair_depth(rig, 0, 0, warm.finish())
        items: queue.Queue[Item | None] = queue.Queue()
        counts = {"sequences": 0, "dropped": 0}
        feeder = threading.Thread(target=feed, args=(frames, rate_hz, seconds, items, counts), daemon=True)
        latencies, clouds, stream = [], 0, None
        cpu, wall = time.process_time(), time.monotonic()
        feeder.start()
        while (item := items.get()) is not None:
            _, index, frame, arrived = item
            if index == 0:
                stream = codecs[0].stream(full_scale)
            assert stream is not None
            stream.add(frame)
            if index == len(frames) - 1:
                depth = pair_depth(rig, 0, 0, stream.finish())
                latencies.append((time.monotonic() - arrived) * 1e3)
                clouds += int(np.isfinite(depth).any())
        wall, cpu = time.monotonic() - wall, time.process_time() - cpu
        feeder.join()
    width, height = config.cameras[0].resolution
    return {
        "benchmark": "throughput",
        "camera": f"{width}x{height} at {rate_hz:g} Hz",
        "sequence": f"live mode's {config.scan.live.codec}: {len(frames)} frames",
        "seconds": round(wall, 2),
        "camera_sequences_per_s": round(rate_hz / len(frames), 2),
        "clouds_per_s": round(clouds / wall, 2),
        "sequences": counts["sequences"],
        "dropped": counts["dropped"],
        "latency_ms": {
            "p50": round(float(np.percentile(latencies, 50)), 1),
            "p99": round(float(np.percentile(latencies, 99)), 1),
        },
        "cpu_s_per_cloud": round(cpu / max(clouds, 1), 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--rate", type=float, default=120.0, help="the camera's frames per second")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long the camera delivers")
    args = parser.parse_args()
    print(json.dumps(measure(args.rate, args.seconds)))


if __name__ == "__main__":
    main()
