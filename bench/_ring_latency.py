"""The dissertation's ring codecs on the default bench, as bench/throughput.py states them: the
frames arriving at the camera's rate and each decoded as it arrives, then, from the last frame's
arrival, the time to the ring points (the stream's last step, triangulation and the PointSet) and,
for rings, to the surface and its colour between the rings; for radial, which codes every pixel as
the dense codecs do, also the time to its organised cloud, the figure they are measured by
(bench/speed.py, the throughput cases) (median and worst of the repeats)."""

from __future__ import annotations

import statistics
import time
from typing import Any

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.patterns.stream import decode_streamed
from rig.pipeline.scan import capture, make_codec, reconstruct_pair
from rig.progress import ProgressTracker

RING_CODECS = ("rings", "radial")


def ring_latency(codec_name: str, rate_hz: float = 120.0, repeats: int = 5) -> dict[str, Any]:
    data = load_config().with_codec(codec_name).model_dump(mode="json")
    data["scan"]["surface"]["colour"] = "area"  # the colour between the rings, as a scan stores it
    with open_rig(config_from_dict(data, f"ring latency {codec_name}")) as rig:
        codec = make_codec(rig, 0)
        frames = capture(rig, [codec], ProgressTracker(None))[(0, 0)]
        reconstruct_pair(rig, 0, 0, decode_streamed(codec, frames, 255), source=0)  # compiled, terms cached
        to_points, to_cloud, to_surface, points = [], [], [], 0
        for _ in range(repeats):
            stream, start, arrival = codec.stream(255), time.perf_counter(), 0.0
            for k, frame in enumerate(frames):
                arrival = start + k / rate_hz
                while (wait := arrival - time.perf_counter()) > 0:
                    time.sleep(wait)
                stream.add(frame)
            corr = stream.finish()
            finished, elapsed = time.perf_counter(), {}
            pair = reconstruct_pair(rig, 0, 0, corr, source=0, elapsed=elapsed)
            done = time.perf_counter()
            to_cloud.append((finished - arrival + elapsed["triangulate"]) * 1e3)  # radial: the organised cloud
            to_points.append(to_cloud[-1] + elapsed["pointset"] * 1e3)
            to_surface.append((done - arrival) * 1e3)
            points = len(pair.points)
    frame_bytes = sum(f.nbytes for f in frames)
    measured = {
        "codec": codec_name,
        "frames": len(frames),
        "frame_mb": round(frame_bytes / 2**20, 1),
        "points": points,
        "last_frame_to_points_ms": round(statistics.median(to_points), 1),
        "last_frame_to_points_ms_worst": round(max(to_points), 1),
    }
    if codec_name == "radial":
        measured["last_frame_to_cloud_ms"] = round(statistics.median(to_cloud), 1)
        measured["last_frame_to_cloud_ms_worst"] = round(max(to_cloud), 1)
    if codec_name == "rings":
        measured["last_frame_to_surface_ms"] = round(statistics.median(to_surface), 1)
        measured["last_frame_to_surface_ms_worst"] = round(max(to_surface), 1)
    return measured
