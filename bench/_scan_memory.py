"""A scan's memory, for bench/speed.py: the peak RSS of a whole `slrig scan`, and on a rig kept open
as the daemon keeps it, how far a second scan raises the peak, in a fresh process each."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

from rig.config import RigConfig

# A scan's memory: peak RSS of a whole `slrig scan` (VmHWM, not ru_maxrss: Linux keeps ru_maxrss
# across fork and exec, so a child of this large process reported the parent's size, 1.3 GB against
# 0.9 measured alone); then, on one open rig as the daemon holds it, a scan after a first one, its
# peak (VmHWM reset by writing 5 to clear_refs) less what the process held before it (the fixed
# overhead: imports, numba's loops, the simulator, its ray casts and ground truth, the pair's terms).
_PEAK_SNIPPET = """
import json, os, sys
import rig.workers
from rig.cli import main
from rig.workers import release_free_memory
if os.environ.get("SPEED_MAP_FROM_BYTES"):  # --map-from-kb: arrays from that size mapped, whatever the rig
    rig.workers._MMAP_FROM_BYTES = rig.workers._MMAP_AT_MOST = int(os.environ["SPEED_MAP_FROM_BYTES"])
    rig.workers.tune_malloc()
def status_mb(key):
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith(key + ":")) / 1024
config_file = sys.argv[3:]  # the rig to scan, where not the default
rig_options = ["--config", *config_file] if config_file else []
code = main(["scan", "--codec", sys.argv[1], "--out", sys.argv[2] + "-first", "--json", *rig_options])
whole = status_mb("VmHWM")
from pathlib import Path
from rig.assembly import open_rig
from rig.config import load_config
from rig.service.tasks import scan_to_directory
with open_rig(load_config(*config_file).with_codec(sys.argv[1])) as rig:
    scan_to_directory(rig, Path(sys.argv[2] + "-warm"), "warm")
    release_free_memory()
    fixed = status_mb("VmRSS")
    try:  # the peak starts again from what the process holds now
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:  # a kernel that will not reset it: no figure per scan
        fixed = None
    scan_to_directory(rig, Path(sys.argv[2]), "measured")
    second = status_mb("VmHWM")
print(json.dumps({"exit": code, "peak_rss_mb": whole, "fixed_mb": fixed, "second_peak_mb": second}))
"""


def peak_memory(
    codec_name: str, config: RigConfig | None = None, map_from_bytes: int | None = None
) -> dict[str, float | None]:
    """A codec's scan memory (see _PEAK_SNIPPET), in a fresh process; `map_from_bytes`: arrays from
    that size mapped rather than kept in the heap (what the heap's holes add: decision 0044)."""
    env = {**os.environ, "SPEED_MAP_FROM_BYTES": str(map_from_bytes)} if map_from_bytes else None
    with tempfile.TemporaryDirectory() as tmp:
        rig_file = []
        if config is not None:  # another rig than the default: as a file, for a fresh process
            rig_file = [os.path.join(tmp, "rig.yaml")]
            Path(rig_file[0]).write_text(yaml.safe_dump(config.model_dump(mode="json")))
        out = subprocess.run(
            [sys.executable, "-c", _PEAK_SNIPPET, codec_name, os.path.join(tmp, "scan"), *rig_file],
            env=env,
            capture_output=True,
            text=True,
            check=True,
            timeout=600,
        )
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    if measured["exit"]:
        raise RuntimeError(f"slrig scan --codec {codec_name} failed: {out.stderr[-2000:]}")
    peak, fixed = measured["peak_rss_mb"], measured["fixed_mb"]
    return {
        "scan_peak_rss_mb": round(peak, 1),
        "fixed_overhead_mb": None if fixed is None else round(fixed, 1),
        "per_scan_mb": None if fixed is None else round(measured["second_peak_mb"] - fixed, 1),
    }
