"""systemd's notification protocol, written here (one datagram per message, no dependency).

A no-op when NOTIFY_SOCKET is unset (not started by systemd). The watchdog interval comes from
WATCHDOG_USEC (for this process, if WATCHDOG_PID says so); pinging at half of it is the rule of
sd_watchdog_enabled(3).
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Mapping

log = logging.getLogger(__name__)


class Notifier:
    def __init__(self, environ: Mapping[str, str] | None = None) -> None:
        env = os.environ if environ is None else environ
        path = env.get("NOTIFY_SOCKET") or None
        self._address = "\0" + path[1:] if path and path.startswith("@") else path  # "@": abstract namespace
        usec = env.get("WATCHDOG_USEC", "")
        pid = env.get("WATCHDOG_PID", "")
        mine = not pid or pid == str(os.getpid())
        self.watchdog_interval_s = int(usec) / 1e6 / 2 if usec.isdigit() and int(usec) > 0 and mine else None

    @property
    def enabled(self) -> bool:
        return self._address is not None

    def notify(self, *lines: str) -> None:
        if self._address is None:
            return
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
                sock.sendto("\n".join(lines).encode(), self._address)
        except OSError as exc:  # systemd gone: nothing to tell, nothing to stop for
            log.warning("cannot notify systemd: %s", exc)
