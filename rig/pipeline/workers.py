"""One pool of threads for the pipeline's per-pixel numpy work (numpy releases the GIL in its
loops, so batches of pixels or triangles run on every core without copying arrays to processes)."""

from __future__ import annotations

import itertools
import os
import threading
from concurrent.futures import ThreadPoolExecutor

THREADS = max(1, min(4, os.cpu_count() or 1))

_lock = threading.Lock()
_executor: ThreadPoolExecutor | None = None


def pool() -> ThreadPoolExecutor:
    """The shared pool (made on first use)."""
    global _executor
    with _lock:
        if _executor is None:
            _executor = ThreadPoolExecutor(max_workers=THREADS, thread_name_prefix="slrig-pixels")
        return _executor


def batches(count: int, per_thread: int = 2) -> list[tuple[int, int]]:
    """[start, end) ranges splitting `count` items into about `per_thread` batches per thread."""
    n = max(1, min(count, THREADS * per_thread))
    bounds = [round(count * k / n) for k in range(n + 1)]
    return [(a, b) for a, b in itertools.pairwise(bounds) if b > a]
