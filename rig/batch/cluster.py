"""Where a batch runs: Dask's distributed scheduler, on a local cluster of processes sized to this
machine (the default) or on a running scheduler that `dask scheduler` / `dask worker` started on
many machines. Each worker offers its memory as the resource MEMORY (bytes), and each scan asks for
what the memory model says it needs, so that a worker never takes more scans than it can hold."""

from __future__ import annotations

import importlib.util
import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from rig.assembly import FIXED_BYTES, available_memory
from rig.errors import UsageError

MEMORY = "MEMORY"  # the resource each worker offers and each scan asks for, in bytes
CONNECT_TIMEOUT_S = 30
# One thread per worker process: the processes are the parallelism (numpy, numba and OpenCV
# would otherwise each start a thread per core in every worker).
WORKER_ENVIRONMENT = {"SLRIG_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
INSTALL = "pip install -e '.[dask]' (or pip install 'distributed>=2024.8')"


class DaskMissingError(UsageError):
    """Raised when `slrig batch` runs where Dask's distributed package is not installed."""


@dataclass
class Cluster:
    """A connected client and what its workers offer."""

    client: Any  # distributed.Client
    dashboard: str | None
    worker_memory: list[int]  # MEMORY each worker offers (empty: none offers it)

    @property
    def workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1)["workers"])


def require_dask() -> None:
    if importlib.util.find_spec("distributed") is None:
        raise DaskMissingError(f"slrig batch runs on Dask, which is not installed here: {INSTALL}")


def local_worker_memory(workers: int, available: int | None = None) -> int:
    """Bytes each of `workers` local workers may hold: this machine's available memory shared out."""
    room = available if available is not None else available_memory()
    return max(1, (room or 4 * FIXED_BYTES * workers) // workers)


@contextmanager
def connect(scheduler: str = "local", workers: int | None = None) -> Iterator[Cluster]:
    """A client on a new local cluster (`scheduler` "local": `workers` processes, default one per
    core) or on the running scheduler at `scheduler` (tcp://HOST:8786; `workers` must be None)."""
    require_dask()
    from distributed import Client, LocalCluster

    if scheduler == "local":
        count = workers if workers is not None else (os.cpu_count() or 1)
        if count < 1:
            raise UsageError(f"--workers {count}: at least one worker")
        memory = local_worker_memory(count)
        cluster = LocalCluster(
            n_workers=count,
            threads_per_worker=1,
            processes=True,
            memory_limit=memory,
            resources={MEMORY: max(1, memory - FIXED_BYTES)},
            env=WORKER_ENVIRONMENT,
            dashboard_address=":0",
            silence_logs=logging.ERROR,
        )
        try:
            with Client(cluster, timeout=CONNECT_TIMEOUT_S) as client:
                yield Cluster(client, _dashboard(client), _memories(client))
        finally:
            cluster.close(timeout=CONNECT_TIMEOUT_S)
        return
    if not scheduler.startswith(("tcp://", "tls://")):
        raise UsageError(f"--scheduler {scheduler}: 'local', or a scheduler's address such as tcp://HOST:8786")
    if workers is not None:
        raise UsageError("--workers: a running scheduler has the workers it has (start more with `dask worker`)")
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
    except OSError as exc:
        answer = f"no scheduler answered within {CONNECT_TIMEOUT_S} s ({exc})"
        raise UsageError(f"--scheduler {scheduler}: {answer}") from exc
    with client:
        yield Cluster(client, _dashboard(client), _memories(client))


def _memories(client: Any) -> list[int]:
    offered = [w.get("resources", {}).get(MEMORY) for w in client.scheduler_info(n_workers=-1)["workers"].values()]
    return [int(m) for m in offered if m] if offered and all(offered) else []


def _dashboard(client: Any) -> str | None:
    try:
        return str(client.dashboard_link)
    except (KeyError, AttributeError):  # no dashboard (bokeh is not installed)
        return None
