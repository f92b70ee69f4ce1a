"""Keeping pace with the camera (rig.pipeline.sustained): sequences finished on a worker thread while
the next is captured; when finishing falls behind, whole sequences are dropped and counted, the
newest is published, and a failure or a stuck finish reaches the caller."""

from __future__ import annotations

import threading
import time

import pytest

from rig.errors import ScanError
from rig.pipeline.sustained import SequenceWorker


def test_a_slow_finish_drops_whole_sequences_and_publishes_the_newest() -> None:
    release = threading.Event()
    started = threading.Event()
    published: list[tuple[int, ...]] = []

    def finish(frames: tuple[int, ...]) -> tuple[int, ...]:
        started.set()
        assert release.wait(30), "the test never released the worker"
        return frames

    worker: SequenceWorker[tuple[int, ...], tuple[int, ...]] = SequenceWorker(finish, published.append)
    worker.submit((1, 1, 1))
    assert started.wait(30)  # the worker is on sequence 1 ...
    for n in (2, 3, 4):  # ... while three more are captured: 2 and 3 wait in turn and are replaced
        worker.submit((n, n, n))
    assert worker.dropped == 2
    release.set()
    worker.close(30)
    assert published == [(1, 1, 1), (4, 4, 4)]  # whole sequences, the newest last


def test_when_finishing_keeps_up_nothing_is_dropped() -> None:
    published: list[int] = []
    worker: SequenceWorker[int, int] = SequenceWorker(lambda n: n * 10, published.append)
    for n in range(1, 6):
        worker.submit(n)
        deadline = time.monotonic() + 30
        while len(published) < n:  # the capture of the next sequence takes longer than this finish
            assert time.monotonic() < deadline
            time.sleep(0.001)
    worker.close(30)
    assert published == [10, 20, 30, 40, 50] and worker.dropped == 0


def test_a_failure_on_the_worker_reaches_the_caller() -> None:
    failed = threading.Event()

    def finish(n: int) -> int:
        failed.set()
        raise ValueError(f"sequence {n} did not decode")

    worker: SequenceWorker[int, int] = SequenceWorker(finish, lambda n: None)
    worker.submit(1)
    assert failed.wait(30)
    deadline = time.monotonic() + 30
    with pytest.raises(ValueError, match="sequence 1"):
        while time.monotonic() < deadline:  # the next submit raises it, once the worker has stopped
            worker.submit(2)
            time.sleep(0.01)
    with pytest.raises(ValueError, match="sequence 1"):  # and so does close
        worker.close(30)


def test_a_finish_that_never_ends_fails_close_within_its_timeout() -> None:
    release = threading.Event()

    def finish(n: int) -> int:
        release.wait(30)  # stuck, as a driver or a decoder might be
        return n

    worker: SequenceWorker[int, int] = SequenceWorker(finish, lambda n: None)
    worker.submit(1)
    with pytest.raises(ScanError, match=r"not finished within 0\.2 s"):
        worker.close(0.2)
    release.set()
