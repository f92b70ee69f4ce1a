"""Loopback ports for the processes a test starts (daemons, browsers).

A port the kernel hands out for `bind(0)` lies in the ephemeral range, the same range every outgoing
connection's local port is drawn from, and is free only until it is closed again: another xdist
worker or any client may take it before the child process binds it. So each worker draws from its
own block below the ephemeral range, and a caller that still meets "in use" draws again."""

from __future__ import annotations

import itertools
import os
import random
import socket

_BLOCK = 1000
_LOWEST = 20000  # below Linux's default ephemeral range (32768-60999)


def _worker_index() -> int:
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    digits = worker.removeprefix("gw")
    return int(digits) % 12 if digits.isdigit() else 0


_first = _LOWEST + _worker_index() * _BLOCK
_candidates = itertools.cycle(random.Random(os.getpid()).sample(range(_first, _first + _BLOCK), _BLOCK))


def free_port() -> int:
    """A loopback port nobody holds now, from this worker's own block."""
    for _ in range(_BLOCK):
        port = next(_candidates)
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError(f"no free loopback port in {_BLOCK} tries")
