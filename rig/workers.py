"""One pool of threads for the pipeline's per-pixel numpy work (numpy releases the GIL in its
loops, so batches of pixels or triangles run on every core without copying arrays to processes)."""

from __future__ import annotations

import ctypes
import ctypes.util
import itertools
import os
import sys
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np


def _threads() -> int:
    """Up to 4, one per core; $SLRIG_THREADS sets it (a machine shared with other work, the test
    suite running one process per core)."""
    try:
        asked = int(os.environ.get("SLRIG_THREADS", "0"))
    except ValueError:
        asked = 0
    return asked if asked > 0 else max(1, min(4, os.cpu_count() or 1))


THREADS = _threads()
# glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8
# Arrays under _MMAP_FROM_BYTES come from the heap, and it keeps up to _KEEP_FREED_BYTES of freed
# memory for the next arrays; larger arrays are mapped and unmapped (see tune_malloc). A rig of
# larger cameras raises the threshold to its float32 image, up to _MMAP_AT_MOST (heap_images).
# Builds of glibc that refuse a threshold keep their default.
_MMAP_FROM_BYTES = 6 << 20  # 6 MB
_MMAP_AT_MOST = 64 << 20  # a 12 MP camera's float32 image is 49 MB
_KEEP_FREED_BYTES = 1 << 30

# A bound on waiting for work handed to the pool or to beside(): far beyond what any of it takes
# (tens of milliseconds), so that a stuck thread fails the job instead of hanging it.
POOL_WAIT_S = 300.0

_lock = threading.Lock()
_executor: ThreadPoolExecutor | None = None
_beside: ThreadPoolExecutor | None = None


def pool() -> ThreadPoolExecutor:
    """The shared pool (made on first use)."""
    global _executor
    with _lock:
        if _executor is None:
            _executor = ThreadPoolExecutor(max_workers=THREADS, thread_name_prefix="slrig-pixels")
        return _executor


def beside() -> ThreadPoolExecutor:
    """A thread for a stage that runs beside the caller's and puts its own work on the pool (made on
    first use): a pool thread must never wait on the pool, which with one thread would wait on itself.
    The pool takes both stages' batches in turn, so each fills the cores the other leaves idle."""
    global _beside
    with _lock:
        if _beside is None:
            _beside = ThreadPoolExecutor(max_workers=1, thread_name_prefix="slrig-beside")
        return _beside


def tune_malloc() -> None:
    """Tune glibc's allocator for numpy's few, large, short-lived arrays (elsewhere a no-op). Call
    before any thread starts (the rig package does, on import): glibc fixes its arena limit when a
    second thread first allocates.

    - One arena for every thread: glibc gives each new thread its own, and memory freed in one is
      not reused by another (a ring scan's peak RSS rose from 680 to 790 MB with this pool).
    - Arrays under 6 MB (frames, patterns, float32 images of a 1280x1024 camera) come from the heap,
      and freed ones stay there for the next ones (up to _KEEP_FREED_BYTES), without page faults.
      Larger arrays (a cloud's fields) are mapped and given back when freed: kept in the heap too,
      their holes went to smaller arrays and a scan's peak rose above what it held. A second gray
      scan on an open rig (bench/speed.py's peak_memory) raised the peak 118 to 123 MB with every
      array in the heap, 86 to 90 with this threshold. At 4 MB, which maps the float32 images too,
      83 to 84, but decoding and the fast path fault their images in: gray decode 9.4 -> 10.4 ms
      (4.3 -> 4.8 times the memory floor), last frame to cloud 10.2 -> 15.4 ms, radial decode
      229 -> 283 ms. A rig of larger cameras raises the threshold to their float32 images
      (heap_images, decision 0040).
      release_free_memory() returns what a job left in the heap."""
    libc = _glibc()
    if libc is None:
        return
    libc.mallopt(_M_ARENA_MAX, 1)
    libc.mallopt(_M_MMAP_THRESHOLD, _MMAP_FROM_BYTES)
    libc.mallopt(_M_TRIM_THRESHOLD, _KEEP_FREED_BYTES)


def heap_images(pixels: int) -> None:
    """Arrays as large as a float32 image of `pixels` (the rig's largest camera) come from the heap,
    and stay there when freed, so that a sensor beyond 1280x1024 does not fault every image of every
    sequence in again; at least tune_malloc's 6 MB, at most _MMAP_AT_MOST (decision 0040). Set as a
    rig opens (rig.assembly.open_rig), for the process: the last rig opened decides."""
    libc = _glibc()
    if libc is not None:
        libc.mallopt(_M_MMAP_THRESHOLD, min(max(_MMAP_FROM_BYTES, 4 * pixels + (1 << 20)), _MMAP_AT_MOST))


def release_free_memory() -> None:
    """Return the heap's free pages to the system (glibc's malloc_trim; elsewhere a no-op): after a
    job, so that an idle daemon does not hold what a scan freed."""
    libc = _glibc()
    if libc is not None:
        libc.malloc_trim(0)


def _glibc() -> ctypes.CDLL | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.mallopt, libc.malloc_trim  # noqa: B018 - musl has neither
    except (OSError, AttributeError):
        return None
    return libc


BLOCK_POINTS = 1 << 16  # points a pass over a cloud takes at a time: a few MB of temporaries, never a copy


def point_blocks(count: int, size: int = BLOCK_POINTS) -> Iterator[slice]:
    """Consecutive slices of at most `size` items covering `count` (a cloud's points a block at a time)."""
    for start in range(0, count, size):
        yield slice(start, min(count, start + size))


def batches(count: int, per_thread: int = 2) -> list[tuple[int, int]]:
    """[start, end) ranges splitting `count` items into about `per_thread` batches per thread."""
    n = max(1, min(count, THREADS * per_thread))
    bounds = [round(count * k / n) for k in range(n + 1)]
    return [(a, b) for a, b in itertools.pairwise(bounds) if b > a]


def in_row_strips(rows: int, work: Callable[[slice], object], per_thread: int = 1) -> None:
    """Run `work(rows_slice)` over horizontal strips of an image `rows` high on the pool and wait for
    all of them. Row strips of C-ordered arrays are contiguous, so numpy and the compiled loops
    (rig.kernels.dense) write into them in place. Not for work already on the pool."""
    spans = batches(rows, per_thread)
    if len(spans) == 1:
        work(slice(0, rows))
        return
    futures = [pool().submit(work, slice(a, b)) for a, b in spans]
    for future in futures:
        future.result()


def full_on_pool(shape: tuple[int, ...], value: float, dtype: type | np.dtype) -> np.ndarray:
    """np.full, its rows filled on the pool (a large array's pages are faulted in on every core).
    Not for work already on the pool."""
    out = np.empty(shape, dtype)

    def fill(rows: slice) -> None:
        out[rows] = value

    in_row_strips(shape[0], fill)
    return out
