"""Speed and memory of the simulated bench and the reconstruction; prints one JSON object.

- simulated frame time at 1280x1024 after the first ray cast (median of 30 random patterns);
- per codec, one 1280x1024 capture (medians of 7): the last frame to the cloud with the frames
  arriving at the projector's rate (120 Hz, a LightCrafter's 8-bit patterns) and decoded as they
  arrive (the cloud: the organised cloud of rig.pipeline.organised where it covers the pair, points,
  normals and colours; else the PointSet, with the surface between the rings); the stream decoder fed
  every frame back to back after a copy of 256 MiB has pushed frames and state out of the caches
  (as a camera's frames arrive: written to memory), as a multiple of the memory floor (its frames'
  bytes read once at the machine's copy bandwidth), and again with the frames in the caches; the
  batch (reference) decoder, triangulation (with normals on the fast path), the PointSet step and,
  for ring codecs, the surface and its colour between the rings (colour by the density-compensated
  interpolant, scan.surface.colour = area);
- live mode on the default bench for 5 s (rig.pipeline.live, as `slrig live --seconds 5 --json`):
  clouds per second and the latency from a sequence's last frame to its depth image;
- peak resident memory of a whole `slrig scan` per codec, each in a fresh process, and its ratio to
  the bytes of the scan's frames;
- recognition: the descriptor of the default 32-ring scan (its cloud and the surface between its
  rings, as `slrig identify` reads it; median of 5), and identification against a gallery of 1000
  entries (reading the SQLite gallery and scoring every entry; median of 20).

    python bench/speed.py            # JSON
    python bench/speed.py --docs   # also rewrite the speed table in the manual (docs/)
    python bench/speed.py --memory rings [--map-from-kb 256]   # one codec's memory columns alone
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import as_measured, markdown_table, replace_block
from _scan_memory import peak_memory

from rig.assembly import open_rig
from rig.config import RigConfig, config_from_dict, load_config
from rig.opened_rig import Rig
from rig.patterns import Codec, Correspondence, codec_names
from rig.patterns.stream import decode_streamed
from rig.pipeline.live import live_codecs, run_live
from rig.pipeline.scan import capture, make_codec, pair_cloud, reconstruct_pair, run_scan
from rig.progress import ProgressTracker
from rig.recognition.descriptor import describe
from rig.recognition.gallery import Gallery
from rig.recognition.identify import identify

RATE_HZ = 120.0  # a DLP LightCrafter 4500 showing 8-bit patterns


def frame_time() -> dict[str, float]:
    config = load_config()
    with open_rig(config) as rig:
        projector, camera = rig.projectors[0], rig.cameras[0]
        width, height = projector.resolution
        projector.show(np.full((height, width), 255, np.uint8))
        t = time.perf_counter()
        camera.capture()
        first = time.perf_counter() - t
        rng = np.random.default_rng(0)
        patterns = [rng.integers(0, 256, (height, width), dtype=np.uint8) for _ in range(30)]
        times = []
        for pattern in patterns:
            t = time.perf_counter()
            projector.show(pattern)
            camera.capture()
            times.append(time.perf_counter() - t)
    return {
        "first_frame_s": round(first, 3),
        "frame_ms_median": round(statistics.median(times) * 1e3, 1),
        "frame_ms_p90": round(float(np.percentile(times, 90)) * 1e3, 1),
    }


EVICT_MB = 256  # copied to push frames and decoder state out of every cache (far above any L3)


class CacheEvictor:
    """Pushes everything out of the CPU caches by copying EVICT_MB, so that a decoder reads its
    frames from memory, as it does frames a camera has just written there."""

    def __init__(self) -> None:
        self._source = np.ones(EVICT_MB << 20, np.uint8)
        self._target = np.empty_like(self._source)
        self.bytes = self._source.nbytes

    def __call__(self) -> None:
        np.copyto(self._target, self._source)


@functools.cache
def evictor() -> CacheEvictor:
    return CacheEvictor()


def copy_bandwidth_gb_s(repeats: int = 7) -> float:
    """This machine's memory floor: bytes read per second by one copy of a large uint8 array
    (the evictor's copy, best of `repeats`). A decoder that reads its frames once cannot beat it."""
    copy, best = evictor(), float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        copy()
        best = min(best, time.perf_counter() - t)
    return copy.bytes / best / 1e9


def cloud_now(rig: Rig, corr: Correspondence) -> object:
    """The pair's cloud: the organised cloud where the fast path covers the pair, else the PointSet."""
    fast = pair_cloud(rig, 0, 0, corr)
    return fast if fast is not None else reconstruct_pair(rig, 0, 0, corr, source=0)


def last_frame_to_cloud(rig: Rig, codec: Codec, frames: list[np.ndarray], rate_hz: float, repeats: int) -> float:
    """Median ms from the arrival of the last frame to the cloud, the frames arriving at `rate_hz`
    and each decoded as it arrives (a decoder that falls behind the rate adds its backlog)."""
    period, latencies = 1.0 / rate_hz, []
    for _ in range(repeats):
        stream = codec.stream(255)
        start = time.perf_counter()
        for k, frame in enumerate(frames):
            arrival = start + k * period
            while (wait := arrival - time.perf_counter()) > 0:
                time.sleep(wait)
            stream.add(frame)
        cloud_now(rig, stream.finish())
        latencies.append(time.perf_counter() - arrival)
    return statistics.median(latencies) * 1e3


def reconstruction(
    codec_name: str,
    repeats: int = 7,
    config: RigConfig | None = None,
    bandwidth_gb_s: float | None = None,
    rate_hz: float = RATE_HZ,
) -> dict[str, float]:
    """Median decode, triangulate and PointSet times of one capture, after a first untimed pass
    (which computes the per-calibration terms), and the last frame to the cloud with the frames
    arriving at `rate_hz`; `config`: another rig than the default's."""
    config = (config or load_config()).with_codec(codec_name)
    data = config.model_dump(mode="json")
    data["scan"]["surface"]["colour"] = "area"  # ring codecs: time the colour between the rings too
    config = config_from_dict(data, "speed")
    with open_rig(config) as rig:
        codec = make_codec(rig, 0)
        frames = capture(rig, [codec], ProgressTracker(None))[(0, 0)]
        reconstruct_pair(rig, 0, 0, decode_streamed(codec, frames, 255), source=0)
        decode, warm, batch, tri, pointset, surface = [], [], [], [], [], []
        evict = evictor()
        for _ in range(repeats):
            elapsed: dict[str, float] = {}
            t0 = time.perf_counter()
            codec.decode(frames, 255)
            batch.append(time.perf_counter() - t0)
            evict()
            t0 = time.perf_counter()
            corr = decode_streamed(codec, frames, 255)
            decode.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            decode_streamed(codec, frames, 255)  # again, its frames now in the caches
            warm.append(time.perf_counter() - t0)
            reconstruct_pair(rig, 0, 0, corr, source=0, elapsed=elapsed)
            tri.append(elapsed["triangulate"])
            pointset.append(elapsed["pointset"])
            surface.append(elapsed.get("surface", 0.0))
        latency = last_frame_to_cloud(rig, codec, frames, rate_hz, repeats)
    d, w, b, t, p, s = (statistics.median(x) * 1e3 for x in (decode, warm, batch, tri, pointset, surface))
    frame_bytes = sum(f.nbytes for f in frames)
    floor_ms = frame_bytes / ((bandwidth_gb_s or copy_bandwidth_gb_s()) * 1e9) * 1e3
    return {
        "frames": len(frames),
        "frame_mb": round(frame_bytes / 1e6, 1),
        "last_frame_to_cloud_ms": round(latency, 1),
        "rate_hz": rate_hz,
        "decode_ms": round(d, 1),  # the stream a scan uses, fed every frame back to back, caches evicted first
        "decode_warm_ms": round(w, 1),  # the same with its frames in the caches
        "batch_decode_ms": round(b, 1),  # the reference decoder
        "decode_over_memory_floor": round(d / floor_ms, 1),  # decode against reading its frames once
        "triangulate_ms": round(t, 1),
        "decode_triangulate_ms": round(d + t, 1),
        "pointset_ms": round(p, 1),
        "surface_ms": round(s, 1),  # ring codecs: the surface and its colour between the rings
    }


def recognition(gallery_entries: int = 1000) -> dict[str, float]:
    config = load_config().with_codec("rings")
    with open_rig(config) as rig:
        result = run_scan(rig, "rings")
        axis = -np.asarray(rig.projector_models[0].axis, float)
    assert result.mesh is not None
    points = np.concatenate([result.cloud.points, result.mesh.vertices])
    describe(points, axis)  # untimed: first calls
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        descriptor = describe(points, axis)
        times.append(time.perf_counter() - t0)
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        with Gallery(Path(tmp) / "gallery.db", create=True) as gallery:
            for i in range(gallery_entries):
                noisy = descriptor.features * rng.normal(1.0, 0.2, descriptor.features.shape)
                gallery.add(f"object-{i % 100}", f"scan-{i}", replace(descriptor, features=noisy))
        lookups = []
        for _ in range(20):
            t0 = time.perf_counter()
            with Gallery(Path(tmp) / "gallery.db") as gallery:
                identify(descriptor.features, *gallery.features())
            lookups.append(time.perf_counter() - t0)
    return {
        "points": len(points),
        "describe_ms": round(statistics.median(times) * 1e3, 1),
        "gallery_entries": gallery_entries,
        "identify_ms": round(statistics.median(lookups) * 1e3, 1),
    }


def live(seconds: float = 5.0) -> dict[str, object]:
    """Live mode on the default bench for `seconds`: its figures as `slrig live --json` gives them."""
    with open_rig(load_config()) as rig:
        deadline = time.monotonic() + seconds
        stats = run_live(rig, lambda frame: None, lambda: time.monotonic() < deadline)
        codec = live_codecs(rig)[0]
    return {"codec": codec.name, "steps": getattr(codec.params, "steps", None), **stats.as_dict()}


def codec_row(name: str, bandwidth_gb_s: float) -> dict[str, float | None]:
    config, label = as_measured(load_config(), name)
    linear = config if label != name else None  # the rig a codec needing linear light is measured on
    row = reconstruction(name, config=linear, bandwidth_gb_s=bandwidth_gb_s)
    memory = peak_memory(name, linear)
    per_scan = memory["per_scan_mb"]
    return {
        **row,
        **memory,
        "scan_peak_rss_over_frames": round(memory["scan_peak_rss_mb"] / row["frame_mb"], 1),  # type: ignore[operator]
        "per_scan_over_frames": None if per_scan is None else round(per_scan / row["frame_mb"], 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--docs", "--readme", dest="readme", action="store_true", help="rewrite the speed table in the manual (docs/)"
    )
    parser.add_argument("--memory", metavar="CODEC", help="only the memory columns of this codec's row")
    parser.add_argument("--map-from-kb", type=int, help="with --memory: arrays from this size mapped, not heaped")
    args = parser.parse_args()
    if args.memory:
        config, label = as_measured(load_config(), args.memory)
        mapped = None if args.map_from_kb is None else args.map_from_kb << 10
        memory = peak_memory(args.memory, config if label != args.memory else None, mapped)
        print(json.dumps({"codec": args.memory, "map_from_kb": args.map_from_kb, **memory}))
        return
    result = {
        "benchmark": "speed",
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "simulated_frame_1280x1024": frame_time(),
        "copy_bandwidth_gb_s": round(bandwidth := copy_bandwidth_gb_s(), 2),
        "codecs": {name: codec_row(name, bandwidth) for name in codec_names()},
        "live": live(),
        "recognition": recognition(),
    }
    print(json.dumps(result))
    if args.readme:
        replace_block("speed-table", readme_text(result))


def readme_text(result: dict[str, Any]) -> str:
    """The manual's speed section from a measurement."""
    f, r, lv = result["simulated_frame_1280x1024"], result["recognition"], result["live"]
    rows = [
        [
            as_measured(load_config(), name)[1],
            c["frames"],
            c["last_frame_to_cloud_ms"],
            c["decode_ms"],
            c["decode_over_memory_floor"],
            c["decode_warm_ms"],
            c["batch_decode_ms"],
            c["triangulate_ms"],
            c["pointset_ms"],
            c["surface_ms"] or "",
            c["scan_peak_rss_mb"],
            c["fixed_overhead_mb"],
            c["per_scan_mb"],
            c["per_scan_over_frames"],
        ]
        for name, c in result["codecs"].items()
    ]
    table = markdown_table(
        [
            "codec",
            "frames",
            f"last frame to cloud ms (frames at {RATE_HZ:g} Hz)",
            "decode ms (caches evicted)",
            "decode / memory floor",
            "decode ms (frames in cache)",
            "batch decode ms (reference)",
            "triangulate + normals ms",
            "PointSet ms",
            "surface + colour between rings ms",
            "`slrig scan` peak RSS MB",
            "fixed overhead MB",
            "a scan on an open rig MB",
            "that / frame bytes",
        ],
        rows,
    )
    text = (
        f"Simulated 1280x1024 frame: {f['frame_ms_median']} ms median ({f['frame_ms_p90']} ms p90) after "
        f"the first, which casts the rays: {f['first_frame_s']} s.\n\n{table}\n\n"
        f"Live mode ({lv['codec']}, {lv['steps']} steps): {lv['clouds_per_s']} depth images per second on the "
        f"simulated bench (the simulator's frame rate bounds it), {lv['latency_ms']['median']} ms median from a "
        f"sequence's last frame to its depth image ({lv['latency_ms']['p95']} ms p95).\n\n"
        f"Recognition: the descriptor of the default 32-ring scan ({r['points']} points) in {r['describe_ms']} ms; "
        f"identification against {r['gallery_entries']} gallery entries (reading the gallery, scoring each) "
        f"in {r['identify_ms']} ms.\n\n"
        "A scan's memory: the peak RSS of a whole `slrig scan`; then, on a rig kept open as the daemon keeps it, "
        "what the process holds after a first scan (the fixed overhead: Python and its libraries, numba's "
        "compiled loops, the simulator, its ray casts and ground truth, each pair's per-calibration terms) and "
        "how far a second scan raises the peak above it, also as a multiple of the bytes of the scan's frames.\n\n"
        f"The memory floor is the time to read a codec's frames once at this machine's copy bandwidth "
        f"({result['copy_bandwidth_gb_s']} GB/s, `np.copyto` of 256 MiB). "
        f"Measured on {result['cpus']} cores by `python bench/speed.py --docs`."
    )
    return text


if __name__ == "__main__":
    main()
