"""A PJLink class 1 projector on a loopback TCP port, for tests: greeting with or without
authentication, POWR with a warm-up during which commands answer ERR3, INPT, AVMT, ERST, and
faults (no greeting, silence, dropping the connection)."""

from __future__ import annotations

import hashlib
import socket
import threading
import time

from drivers.faults import Fault, FaultPlan
from drivers.pjlink_commands import COMMANDS

QUERY_ANSWERS = {"LAMP": "1200 1", "INST": "11 31 32", "NAME": "bench", "INF1": "FAKE", "INF2": "PJLINK"}
QUERY_ANSWERS |= {"INFO": "loopback", "CLSS": "1"}


class FakePJLinkProjector:
    def __init__(
        self, password: str | None = None, warmup_s: float = 0.0, fault: str = "", plan: FaultPlan | None = None
    ) -> None:
        if plan is not None:  # from the first command on
            if plan.after:
                raise ValueError(f"the PJLink fake's faults start with the first command; got {plan}")
            fault = "silence" if plan.fault is Fault.SILENCE else "drop"
        self.password = password
        self.warmup_s = warmup_s
        self.fault = fault  # "", "no-greeting", "silence", "drop", "late-once" (first reply comes 0.4 s late)
        self.refused: list[str] = []  # command lines answered ERR2 by the command table
        self.power = "0"
        self.warm_until = 0.0
        self.input = "31"
        self.muted = False
        self.received: list[str] = []
        self._server = socket.create_server(("127.0.0.1", 0))
        self._server.settimeout(0.1)  # so the accept loop notices close()
        self.port = self._server.getsockname()[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._server.close()
        self._thread.join(timeout=2)

    def __enter__(self) -> FakePJLinkProjector:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except (TimeoutError, OSError):
                continue
            with conn:
                self._session(conn)

    def _session(self, conn: socket.socket) -> None:
        conn.settimeout(5)
        if self.fault == "no-greeting":
            time.sleep(1.0)
            return
        salt = "498e4a67"
        conn.sendall(b"PJLINK 0\r" if self.password is None else f"PJLINK 1 {salt}\r".encode())
        authenticated = self.password is None
        data = b""
        while not self._stop.is_set():
            try:
                chunk = conn.recv(256)
            except (TimeoutError, OSError):
                return
            if not chunk:
                return
            data += chunk
            while b"\r" in data:
                raw, _, data = data.partition(b"\r")
                line = raw.decode("ascii", "replace")
                if not authenticated:
                    digest = hashlib.md5((salt + (self.password or "")).encode()).hexdigest()
                    if not line.startswith(digest):
                        conn.sendall(b"PJLINK ERRA\r")
                        return
                    line = line[32:]
                    authenticated = True
                self.received.append(line)
                if self.fault == "silence":
                    continue
                if self.fault == "drop":
                    return
                if self.fault == "late-once":
                    self.fault = ""
                    time.sleep(0.4)
                try:
                    conn.sendall(self._answer(line).encode() + b"\r")
                except OSError:
                    return  # the client gave up on this connection

    def _answer(self, line: str) -> str:
        if not line.startswith("%1") or line[6:7] != " ":
            return "%1ERR1"
        body, parameter = line[2:6], line[7:]
        known = COMMANDS.get(body)
        if known is None:
            return f"%1{body}=ERR1"  # undefined command (the class 1 command list)
        refused = known.refuses(parameter)
        if refused is not None:
            self.refused.append(line)
            return f"%1{body}={refused}"
        warming = time.monotonic() < self.warm_until
        if body == "POWR":
            if parameter == "?":
                return f"%1POWR={'3' if warming else self.power}"
            if warming:
                return "%1POWR=ERR3"
            if parameter not in ("0", "1"):
                return "%1POWR=ERR2"
            if parameter == "1" and self.power == "0":
                self.warm_until = time.monotonic() + self.warmup_s
            self.power = parameter
            return "%1POWR=OK"
        if body in ("INPT", "AVMT"):
            if warming or self.power != "1":
                return f"%1{body}=ERR3"
            if body == "INPT":
                self.input = parameter
            else:
                self.muted = parameter in ("11", "31")
            return f"%1{body}=OK"
        if body == "ERST":
            return "%1ERST=000000"
        return f"%1{body}={QUERY_ANSWERS[body]}"
