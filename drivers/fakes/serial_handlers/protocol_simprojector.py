"""`simprojector://<benq|epson|optoma>?power=off&fault=<...>`: a pyserial port with a projector
behind it, speaking its vendor's RS-232 protocol, for tests and demos.

Faults: `silence` (no reply at all), `garbage` (noise, as at a wrong baud rate), `late` (each reply
arrives only after the next command was sent), `unplug` (the port fails on write), `refuse` (every
command is refused), `partial` (the reply stops before its terminator).
"""

from __future__ import annotations

import time
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, Timeout

from drivers.faults import Fault, FaultPlan
from drivers.serial_commands import frames


def _known(vendor: str) -> set[bytes]:
    """The table's frames as this handler receives them (framing stripped)."""
    return {frame.strip(b"\r").rstrip(b"#") for frame in frames(vendor)}


class Serial(SerialBase):
    def open(self) -> None:
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        url = urllib.parse.urlsplit(self._port)
        if url.scheme != "simprojector" or url.netloc not in ("benq", "epson", "optoma"):
            raise SerialException(f"expected simprojector://benq|epson|optoma, got {self._port!r}")
        query = urllib.parse.parse_qs(url.query)
        self.vendor = url.netloc
        self.fault = query.get("fault", [""])[0]
        if "@" in self.fault or self.fault == "disconnect":  # a FaultPlan: from the start, in its own names
            plan = FaultPlan.parse(self.fault)
            if plan.after:
                raise SerialException(f"simprojector: faults start with the first command; got {plan}")
            self.fault = "silence" if plan.fault is Fault.SILENCE else "unplug"
        self.power_on = query.get("power", ["off"])[0] == "on"
        self.blanked = False
        self.source = ""
        self.received: list[bytes] = []
        self._buffer = bytearray()
        self._pending = b""
        self._incoming = bytearray()
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def _reconfigure_port(self) -> None:
        pass

    @property
    def in_waiting(self) -> int:
        return len(self._buffer)

    def reset_input_buffer(self) -> None:
        self._buffer.clear()

    def reset_output_buffer(self) -> None:
        pass

    def read(self, size: int = 1) -> bytes:
        if not self.is_open:
            raise PortNotOpenError()
        timeout = Timeout(self._timeout)
        while len(self._buffer) < size and not timeout.expired():
            time.sleep(0.002)  # nothing more will come: wait out the timeout like a real port
        data = bytes(self._buffer[:size])
        del self._buffer[:size]
        return data

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        if self.fault == "unplug":
            raise SerialException("write failed: [Errno 5] Input/output error (device unplugged)")
        if self._pending:  # the previous command's reply turns up only now
            self._buffer += self._pending
            self._pending = b""
        self._incoming += data
        for command in self._commands():
            reply = self._answer(command)
            if self.fault == "silence":
                continue
            if self.fault == "garbage":
                reply = bytes([0xF3, 0x9C, 0x00, 0xFF, 0x81, 0xE6])
            if self.fault == "partial":
                reply = reply[:-2]
            if self.fault == "late":
                self._pending += reply
            else:
                self._buffer += reply
        return len(data)

    def _commands(self) -> list[bytes]:
        """Complete commands in what was written (BenQ frames end in '#', the others in CR)."""
        out = []
        end = b"#" if self.vendor == "benq" else b"\r"
        while end in self._incoming:
            command, _, rest = bytes(self._incoming).partition(end)
            self._incoming = bytearray(rest)
            command = command.strip(b"\r")
            if command:
                out.append(command)
        return out

    def _answer(self, command: bytes) -> bytes:
        self.received.append(command)
        text = command.decode("ascii", "replace")
        refuse = self.fault == "refuse" or command not in _known(self.vendor)  # the table's frames only
        if self.vendor == "benq":
            echo = (text + "#\r").encode()
            if refuse or not text.startswith("*") or "=" not in text:
                return echo + b"*Illegal format#\r"
            key, value = text[1:].split("=", 1)
            if key == "pow":
                if value == "?":
                    return echo + f"*POW={'ON' if self.power_on else 'OFF'}#\r".encode()
                self.power_on = value == "on"
            elif key == "blank":
                if not self.power_on:
                    return echo + b"*Block item#\r"
                self.blanked = value == "on"
            elif key == "sour":
                self.source = value
            else:
                return echo + b"*Unsupported item#\r"
            return echo + f"*{key.upper()}={value.upper()}#\r".encode()
        if self.vendor == "epson":
            if refuse:
                return b"ERR\r:"
            if text == "PWR?":
                return f"PWR={'01' if self.power_on else '04'}\r:".encode()
            if text in ("PWR ON", "PWR OFF"):
                self.power_on = text == "PWR ON"
            elif text in ("MUTE ON", "MUTE OFF"):
                self.blanked = text == "MUTE ON"
            elif text.startswith("SOURCE "):
                self.source = text.split()[1]
            else:
                return b"ERR\r:"
            return b":"
        # optoma
        if refuse or not text.startswith("~00"):
            return b"F\r"
        code, _, value = text[3:].partition(" ")
        if code == "124":
            return f"OK{int(self.power_on)}\r".encode()
        if code == "00":
            self.power_on = value == "1"
        elif code == "02":
            self.blanked = value == "1"
        elif code == "12":
            self.source = value
        else:
            return b"F\r"
        return b"P\r"
