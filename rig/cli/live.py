"""`slrig live`: repeat the live sequence, print clouds per second and latency."""

from __future__ import annotations

import argparse
import json
import sys
import time

from rig.assembly import open_rig
from rig.config import load_config
from rig.errors import UsageError
from rig.patterns import codec_class
from rig.pipeline import LiveFrame, LiveStats, live_codecs, run_live
from rig.store import depth_image_png, write_atomic

REPORT_EVERY_S = 1.0


def cmd_live(args: argparse.Namespace) -> int:
    if args.seconds is not None and not 0 < args.seconds <= 86400:
        raise UsageError(f"--seconds: {args.seconds} is not in (0, 86400]")
    config = load_config(args.config)
    if args.codec:
        codec_class(args.codec)  # an unknown name fails here, naming the known ones
    if args.codec or getattr(args, "hdr", None) is not None:
        config = config.with_live(args.codec, getattr(args, "hdr", None))
    latest: list[LiveFrame] = []
    stats = LiveStats()
    last_report = [time.monotonic()]

    def publish(frame: LiveFrame) -> None:
        latest[:] = [frame]
        now = time.monotonic()
        if not args.json and now - last_report[0] >= REPORT_EVERY_S:
            last_report[0] = now
            print(
                f"sequence {frame.sequence}: {stats.recent_rate():.2f} clouds/s, "
                f"latency {frame.latency_ms:.1f} ms, {frame.points} points",
                flush=True,
            )

    with open_rig(config) as rig:
        codecs = live_codecs(rig)
        codec = codecs[0]
        deadline = None if args.seconds is None else time.monotonic() + args.seconds
        try:
            run_live(rig, publish, lambda: deadline is None or time.monotonic() < deadline, stats)
        except KeyboardInterrupt:
            print("slrig: live mode stopped", file=sys.stderr)
        summary = {
            "codec": codec.name,
            "params": codec.params.model_dump(mode="json"),
            "frames_per_sequence": sum(c.frame_count for c in codecs),
            "hdr": config.scan.live.hdr,
            **stats.as_dict(),
        }
        if args.depth_png is not None and latest:
            write_atomic(args.depth_png, depth_image_png(latest[0].depths[0]))
            summary["depth_png"] = str(args.depth_png)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        latency = summary["latency_ms"] or {}
        print(
            f"live {codec.name}: {summary['sequences']} sequences in {summary['seconds']} s, "
            f"{summary['clouds_per_s']} clouds/s, {summary['dropped']} dropped; latency from last frame to depth "
            f"median {latency.get('median')} ms, p95 {latency.get('p95')} ms"
        )
    return 0
