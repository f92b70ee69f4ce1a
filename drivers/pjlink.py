"""PJLink class 1 over TCP (port 4352): power, input, blank (AV mute), error status, with MD5
authentication. Every reply is awaited with a finite timeout; ERR1-4 and a refused password
become device errors that say which."""

from __future__ import annotations

import hashlib
import socket

from drivers.base import PowerControl
from drivers.errors import (
    DeviceAuthenticationError,
    DeviceDisconnectedError,
    DeviceError,
    DeviceNotFoundError,
    DeviceProtocolError,
    DeviceTimeoutError,
)
from drivers.options import DeviceConfig

PJLINK_PORT = 4352
ERRORS = {
    "ERR1": "undefined command",
    "ERR2": "parameter out of range",
    "ERR3": "unavailable now (warming up, cooling down or busy)",
    "ERR4": "projector failure",
}
POWER_STATES = {"0": "off", "1": "on", "2": "cooling", "3": "warming"}


class PJLinkPowerControl(PowerControl):
    """A networked projector's housekeeping over PJLink class 1."""

    @classmethod
    def from_config(cls, device: DeviceConfig) -> PJLinkPowerControl:
        """The control a projector config's `power` section (protocol pjlink, host) describes."""
        p = device.power
        return cls(f"{device.name}-power", p.host, p.port, p.password, p.timeout_s)

    def __init__(
        self, name: str, host: str, port: int = PJLINK_PORT, password: str | None = None, timeout_s: float = 3.0
    ) -> None:
        super().__init__(name)
        self.host, self.port, self.password, self.timeout_s = host, port, password, timeout_s
        self._socket: socket.socket | None = None
        self._reader: socket.SocketIO | None = None
        self._prefix = ""

    def _do_open(self) -> None:
        try:
            self._socket = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        except TimeoutError as exc:
            raise DeviceTimeoutError(f"{self.name}: no connection to {self.host}:{self.port}") from exc
        except OSError as exc:
            raise DeviceNotFoundError(f"{self.name}: cannot connect to {self.host}:{self.port}: {exc}") from exc
        try:
            greeting = self._read_line()
            if greeting == "PJLINK 0":
                self._prefix = ""
            elif greeting.startswith("PJLINK 1 ") and len(greeting) == 17:
                if self.password is None:
                    raise DeviceAuthenticationError(f"{self.name}: the projector asks for a PJLink password")
                self._prefix = hashlib.md5((greeting[9:] + self.password).encode()).hexdigest()
            else:
                raise DeviceProtocolError(f"{self.name}: not a PJLink greeting: {greeting!r}")
        except BaseException:
            self._disconnect()
            raise

    def _do_close(self) -> None:
        self._disconnect()

    def _disconnect(self) -> None:
        if self._socket is not None:
            self._socket.close()
        self._socket = None

    def _read_line(self) -> str:
        assert self._socket is not None
        data = bytearray()
        try:
            while not data.endswith(b"\r"):
                chunk = self._socket.recv(1)
                if not chunk:
                    raise DeviceDisconnectedError(f"{self.name}: the projector closed the connection")
                data += chunk
                if len(data) > 512:
                    raise DeviceProtocolError(f"{self.name}: reply too long")
        except TimeoutError as exc:
            raise DeviceTimeoutError(f"{self.name}: no reply within {self.timeout_s:g} s") from exc
        except OSError as exc:
            raise DeviceDisconnectedError(f"{self.name}: connection failed: {exc}") from exc
        try:
            return data[:-1].decode("ascii")
        except UnicodeDecodeError:
            raise DeviceProtocolError(f"{self.name}: garbled reply {bytes(data)!r}") from None

    def command(self, body: str, parameter: str) -> str:
        """Send `%1<body> <parameter>` and return the reply's value (after `=`). After a timeout the
        connection is dropped (a late reply would answer the next command) and made again."""
        self._require_open()
        if self._socket is None:
            self._do_open()  # greeting and authentication are per connection
        assert self._socket is not None
        line = f"{self._prefix}%1{body} {parameter}\r"
        self._prefix = ""  # the digest goes with the first command of a connection only
        try:
            self._socket.sendall(line.encode("ascii"))
        except OSError as exc:
            raise DeviceDisconnectedError(f"{self.name}: connection failed: {exc}") from exc
        try:
            reply = self._read_line()
        except (DeviceTimeoutError, DeviceDisconnectedError):
            self._disconnect()
            raise
        if reply == "PJLINK ERRA":
            raise DeviceAuthenticationError(f"{self.name}: PJLink password refused")
        expected = f"%1{body}="
        if not reply.startswith(expected):
            raise DeviceProtocolError(f"{self.name}: reply {reply!r} does not answer {body}")
        value = reply[len(expected) :]
        if value in ERRORS:
            raise DeviceError(f"{self.name}: {body} {parameter}: {value} {ERRORS[value]}")
        return value

    def _do_power(self, on: bool) -> None:
        self.command("POWR", "1" if on else "0")

    def _do_power_state(self) -> str:
        value = self.command("POWR", "?")
        if value not in POWER_STATES:
            raise DeviceProtocolError(f"{self.name}: unknown power state {value!r}")
        return POWER_STATES[value]

    def _do_select_input(self, name: str) -> None:
        """`name` is PJLink's two digits: type (1 RGB, 2 video, 3 digital, 4 storage, 5 network) and number."""
        if len(name) != 2 or name[0] not in "12345" or not name[1].isalnum():
            raise ValueError(f"{self.name}: a PJLink input is two characters, type 1-5 and number (31); got {name!r}")
        self.command("INPT", name)

    def _do_blank(self, on: bool) -> None:
        self.command("AVMT", "31" if on else "30")

    def error_status(self) -> dict[str, str]:
        value = self.command("ERST", "?")
        names = ("fan", "lamp", "temperature", "cover", "filter", "other")
        levels = {"0": "ok", "1": "warning", "2": "error"}
        if len(value) != 6 or any(c not in levels for c in value):
            raise DeviceProtocolError(f"{self.name}: unexpected error status {value!r}")
        return {n: levels[c] for n, c in zip(names, value, strict=True)}
