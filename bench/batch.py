"""An archive reprocessed on a local Dask cluster (`slrig batch reprocess`) against a plain loop over
the same scans on this machine. Prints one JSON object: scans per minute for the loop (one process,
its pixel threads on every core) and for local clusters of 1 and 2 workers (one thread each), with
and without the cluster's start; the scheduler's own time per scan (a task that does nothing, and
the wall time the cluster took beyond its scans' own); each worker's peak memory; and a projection
for N machines from the measured cost per scan and the bytes each scan reads and writes.

    python bench/batch.py [--docs]

The archive: SCANS scans of the default simulated bench (1280x1024 camera) that kept their frames,
gray and phase in turn, made once in a temporary folder.
"""

from __future__ import annotations

import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

SCANS = 8
SHARED_STORAGE_MB_S = 117.0  # the projection's assumption: shared storage over 1 Gb/s Ethernet
LOOP = """
import sys, time
from pathlib import Path
from rig.batch import find_inputs
from rig.service.tasks import reprocess_to_directory
start = time.monotonic()
for n, item in enumerate(find_inputs([Path(sys.argv[1])])):
    reprocess_to_directory(item.path, Path(sys.argv[2]) / item.name, f"loop-{n}")
print(time.monotonic() - start)
"""


def make_archive(root: Path) -> Path:
    from rig.assembly import open_rig
    from rig.config import load_config
    from rig.service.tasks import scan_to_directory

    scans = root / "scans"
    with open_rig(load_config(None)) as rig:
        for n in range(SCANS):
            codec = ("gray", "phase")[n % 2]
            scan_to_directory(rig, scans / f"scan-{n:02d}", f"20261129-120000-{n:06d}", codec, keep_frames=True)
    return scans


def _peak_rss() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _noop(x: int) -> int:
    return x


def _imported() -> None:
    import rig.batch.tasks  # noqa: F401  (as the loop's process has it imported before its clock starts)


def on_cluster(scans: Path, out: Path, workers: int) -> dict[str, Any]:
    from rig.batch import connect, find_inputs, reprocess_archive

    start = time.monotonic()
    with connect("local", workers=workers) as cluster:
        cluster.client.run(_imported)  # every worker up, with slrig imported
        ready = time.monotonic()
        summary = reprocess_archive(cluster, find_inputs([scans]), out, [])
        ended = time.monotonic()
        tasks = 200
        tick = time.monotonic()
        cluster.client.gather(cluster.client.map(_noop, range(tasks), pure=False))
        per_task_ms = (time.monotonic() - tick) / tasks * 1000
        peaks = cluster.client.run(_peak_rss)
    assert not summary.failed, summary.failed
    own = sum(s["seconds"] for s in summary.done)
    wall = ended - ready
    return {
        "workers": workers,
        "wall_s": round(wall, 2),
        "with_start_s": round(ended - start, 2),
        "scans_per_min": round(60 * SCANS / wall, 2),
        "scans_per_min_with_start": round(60 * SCANS / (ended - start), 2),
        "scan_s_mean": round(own / len(summary.done), 3),
        "beyond_scans_s_per_scan": round((wall * workers - own) / SCANS, 3),
        "task_overhead_ms": round(per_task_ms, 2),
        "peak_memory_mb_per_worker": round(max(peaks.values()) / 1e6),
    }


def measure() -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        scans = make_archive(root)
        read_bytes = sum(p.stat().st_size for p in scans.rglob("*") if p.is_file()) / SCANS
        start = time.monotonic()
        command = [sys.executable, "-c", LOOP, str(scans), str(root / "loop")]
        ran = subprocess.run(command, capture_output=True, text=True)
        if ran.returncode:
            raise SystemExit(ran.stderr)
        loop_with_start = time.monotonic() - start
        loop = float(ran.stdout.split()[-1])
        written = sum(p.stat().st_size for p in (root / "loop").rglob("*") if p.is_file()) / SCANS
        clusters = [on_cluster(scans, root / f"cluster-{w}", w) for w in (1, 2)]
    one, two = clusters
    per_scan_s = one["wall_s"] / SCANS  # one worker, one thread: a core's cost per scan
    io_mb = (read_bytes + written) / 1e6
    return {
        "benchmark": "batch",
        "scans": SCANS,
        "loop": {
            "wall_s": round(loop, 2),
            "with_start_s": round(loop_with_start, 2),
            "scans_per_min": round(60 * SCANS / loop, 2),
        },
        "clusters": clusters,
        "two_over_one": round(one["wall_s"] / two["wall_s"], 3),
        "two_over_loop": round(loop / two["wall_s"], 3),
        "overhead_share": round(two["task_overhead_ms"] / 1000 / two["scan_s_mean"], 5),
        "io_mb_per_scan": round(io_mb, 1),
        "projection": {
            "assumes_shared_storage_mb_s": SHARED_STORAGE_MB_S,
            "core_s_per_scan": round(per_scan_s, 3),
            "scans_per_min": {
                f"{machines} x 2 cores": round(min(60 * 2 * machines / per_scan_s, 60 * SHARED_STORAGE_MB_S / io_mb), 1)
                for machines in (1, 4, 16, 64)
            },
        },
    }


def table(m: dict[str, Any]) -> str:
    loop = m["loop"]
    with_start = round(60 * m["scans"] / loop["with_start_s"], 2)
    rows: list[list[object]] = [["plain loop (one process)", loop["scans_per_min"], loop["wall_s"], with_start, "", ""]]
    for c in m["clusters"]:
        rows.append([
            f"local cluster, {c['workers']} worker{'s' if c['workers'] > 1 else ''}",
            c["scans_per_min"], c["wall_s"], c["scans_per_min_with_start"], c["task_overhead_ms"],
            c["peak_memory_mb_per_worker"],
        ])  # fmt: skip
    header = ["run", "scans/min", "wall s", "scans/min with the start", "ms per task", "peak MB per worker"]
    projected = ", ".join(f"{k}: {v}" for k, v in m["projection"]["scans_per_min"].items())
    return (
        markdown_table(header, rows)
        + f"\n\n{m['scans']} scans of the default bench (gray and phase, 1280x1024, frames kept). Two workers "
        f"against one: {m['two_over_one']}x; against the loop: {m['two_over_loop']}x; the scheduler's time per "
        f"task: {100 * m['overhead_share']:.2f} % of a scan's. Projected scans/min (a core "
        f"takes {m['projection']['core_s_per_scan']} s a scan, a scan reads and writes {m['io_mb_per_scan']} MB, "
        f"shared storage at {m['projection']['assumes_shared_storage_mb_s']:.0f} MB/s, which caps it once "
        f"enough machines share it): {projected}."
    )


def main() -> None:
    run(__doc__ or "", "batch-table", measure, table)


if __name__ == "__main__":
    main()
