"""Plain HTTP to the daemons a test starts on the loopback: one client per process.

`httpx.get()` builds a client per call, and with it a TLS context that loads the CA bundle: 42 ms of
CPU each (httpx 0.28), which the polling loops spent hundreds of times a test, on the cores the
daemon they waited for needed. These calls are plain http: they need no TLS context, and they keep
no connection open (tests kill daemons and start others on ports used before)."""

from __future__ import annotations

import httpx

daemon_http = httpx.Client(verify=False, limits=httpx.Limits(max_keepalive_connections=0))
