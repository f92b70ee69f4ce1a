"""Reprocessing handed to a Dask scheduler (`compute.scheduler`), so that the daemon's one worker
keeps the rig for scans while a cluster decodes stored frames.

The worker hands a reprocessing job over and goes on to the next job; the job stays running until
its task ends, and is then recorded done or failed from the Dask client's thread. The cluster's
workers read the source frames and write the new scan directory at the same paths as the daemon
(shared storage), under the same atomic rules (rig.store.scandir.write_scan). Dask cannot stop a
task once a worker runs it, so a running remote job cannot be cancelled; a daemon that stops
records it interrupted (if the cluster still finishes it, its folder stays beside the interrupted
record, and deleting the job removes both). Dask is an optional extra: it is imported when the
first job is handed over."""

from __future__ import annotations

import logging
import socket
import threading
from collections.abc import Callable
from typing import Any

from rig.service.errors import JobConflictError, RemoteUnavailableError

log = logging.getLogger(__name__)
CONNECT_TIMEOUT_S = 10
Finish = Callable[[str, dict[str, Any] | None, str | None], None]  # job id, its summary or why it failed


class RemoteJobs:
    """The jobs running on the scheduler at `address`, each recorded through `finish` when it ends."""

    def __init__(self, address: str, finish: Finish) -> None:
        self.address = address
        self._finish = finish
        self._client: Any = None
        self._futures: dict[str, Any] = {}
        self._lock = threading.Lock()

    def submit(self, job_id: str, task: Callable[..., dict[str, Any]], *args: Any) -> None:
        """Run `task(*args)` on the cluster as job `job_id`'s work."""
        future = self._connected().submit(task, *args, key=f"reprocess-{job_id}", pure=False)
        with self._lock:
            self._futures[job_id] = future
        future.add_done_callback(lambda done: self._ended(job_id, done))

    def running(self, job_id: str) -> bool:
        with self._lock:
            return job_id in self._futures

    def refuse_cancel(self, job_id: str) -> None:
        if self.running(job_id):
            raise JobConflictError(
                f"job {job_id} is reprocessing on the cluster ({self.address}), where a running task cannot be stopped"
            )

    def close(self) -> list[str]:
        """Let go of the cluster; the jobs still running there (to be recorded interrupted)."""
        with self._lock:
            left, self._futures = list(self._futures), {}
        client, self._client = self._client, None
        if client is not None:
            try:
                client.close(timeout=CONNECT_TIMEOUT_S)
            except Exception:  # a scheduler gone already: nothing to let go of
                log.warning("the Dask client at %s did not close cleanly", self.address)
        return left

    def _connected(self) -> Any:
        if self._client is None:
            try:
                from distributed import Client
            except ImportError as exc:
                raise RemoteUnavailableError(
                    f"compute.scheduler is {self.address}, but Dask is not installed here (pip install -e '.[dask]')"
                ) from exc
            try:
                _reachable(self.address)  # refused at once, not after Dask's retries for CONNECT_TIMEOUT_S
                self._client = Client(self.address, timeout=CONNECT_TIMEOUT_S)
            except OSError as exc:
                raise RemoteUnavailableError(
                    f"compute.scheduler: no Dask scheduler answered at {self.address} ({exc}; waited up to "
                    f"{CONNECT_TIMEOUT_S} s)"
                ) from exc
        return self._client

    def _ended(self, job_id: str, future: Any) -> None:
        with self._lock:
            if self._futures.pop(job_id, None) is None:
                return  # let go of at close: the stop records it
        if future.status == "finished":
            self._finish(job_id, future.result(), None)
            return
        exc = future.exception() if future.status == "error" else None
        why = f"{type(exc).__name__}: {exc}" if exc is not None else f"the cluster dropped it ({future.status})"
        self._finish(job_id, None, f"on the cluster at {self.address}: {why}")


def _reachable(address: str) -> None:
    """OSError unless something listens at the scheduler's host and port (tcp://HOST:PORT)."""
    host, _, port = address.split("://", 1)[1].rpartition(":")
    socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_TIMEOUT_S).close()
