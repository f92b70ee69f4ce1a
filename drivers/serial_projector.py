"""Projector housekeeping over RS-232 (pyserial; the port is a pyserial URL): power, input source
and blank, for the BenQ, Epson ESC/VP21 and Optoma command sets. These protocols cannot time
patterns; an HDMI projector shows them through the display worker, and this driver switches it on,
picks its input and blanks it (its safe, dark state).

Every exchange flushes stale input first (a late reply to an earlier command must never be taken
for this one's answer), waits for a terminator with a finite timeout, and checks the reply.
"""

from __future__ import annotations

import abc
import contextlib
import re
import time
from typing import ClassVar

from drivers.base import PowerControl
from drivers.errors import DeviceDisconnectedError, DeviceNotFoundError, DeviceProtocolError, DeviceTimeoutError
from drivers.machine import access_problem
from drivers.options import DeviceConfig

SIM_HANDLERS = "drivers.fakes.serial_handlers"  # `simprojector://<vendor>?fault=...` URLs for tests and demos


class CommandSet(abc.ABC):
    """One vendor's frames: how to ask, and what the answer means."""

    name: str
    baudrate: int
    terminator: bytes
    inputs: ClassVar[dict[str, str]]

    @abc.abstractmethod
    def power(self, on: bool) -> bytes: ...

    @abc.abstractmethod
    def power_query(self) -> bytes: ...

    @abc.abstractmethod
    def parse_power(self, reply: str) -> str: ...

    @abc.abstractmethod
    def select_input(self, code: str) -> bytes: ...

    @abc.abstractmethod
    def blank(self, on: bool) -> bytes: ...

    @abc.abstractmethod
    def check(self, command: bytes, reply: str) -> None:
        """Raise DeviceProtocolError unless `reply` accepts `command`."""

    def is_echo(self, command: bytes, line: bytes) -> bool:
        """Whether `line` is the projector echoing the command back (its answer follows)."""
        return False

    @abc.abstractmethod
    def answers(self, command: bytes, reply: str) -> bool:
        """Whether `reply` (accepted by check) is the answer to `command`, not to an earlier one."""


class BenQ(CommandSet):
    """`\\r*cmd=value#\\r`; replies echo the command, then `*CMD=VALUE#`; errors `*Illegal format#`,
    `*Unsupported item#`, `*Block item#`."""

    name, baudrate, terminator = "benq", 115200, b"#\r"
    inputs: ClassVar[dict[str, str]] = {"hdmi": "hdmi", "hdmi2": "hdmi2", "vga": "RGB"}

    def power(self, on: bool) -> bytes:
        return f"\r*pow={'on' if on else 'off'}#\r".encode()

    def power_query(self) -> bytes:
        return b"\r*pow=?#\r"

    def parse_power(self, reply: str) -> str:
        match = re.search(r"\*POW=(ON|OFF)#", reply.upper())
        if not match:
            raise DeviceProtocolError(f"benq: unexpected power reply {reply!r}")
        return match.group(1).lower()

    def select_input(self, code: str) -> bytes:
        return f"\r*sour={code}#\r".encode()

    def blank(self, on: bool) -> bytes:
        return f"\r*blank={'on' if on else 'off'}#\r".encode()

    def is_echo(self, command: bytes, line: bytes) -> bool:
        # verbatim (the answer to a set repeats it in capitals); a serial prompt may lead
        return line.strip().lstrip(b">") == command.strip()

    def answers(self, command: bytes, reply: str) -> bool:
        key, _, value = command.decode().strip().lstrip("*").rstrip("#").partition("=")
        match = re.search(r"\*([A-Za-z0-9]+)=([^#]*)#", reply)
        if not match or match.group(1).lower() != key.lower():
            return False
        return value == "?" or match.group(2).lower() == value.lower()

    def check(self, command: bytes, reply: str) -> None:
        for error in ("Illegal format", "Unsupported item", "Block item"):
            if error.lower() in reply.lower():
                raise DeviceProtocolError(f"benq: {command.strip()!r} refused: {error}")
        if "*" not in reply:
            raise DeviceProtocolError(f"benq: unexpected reply {reply!r}")


class Epson(CommandSet):
    """ESC/VP21: `CMD value\\r`, readiness prompt `:`; `PWR?` -> `PWR=01`; errors `ERR`."""

    name, baudrate, terminator = "epson", 9600, b":"
    inputs: ClassVar[dict[str, str]] = {"hdmi": "30", "hdmi2": "A0", "vga": "10", "video": "40"}
    _power: ClassVar[dict[str, str]] = {
        "00": "off",
        "01": "on",
        "02": "warming",
        "03": "cooling",
        "04": "off",
        "05": "fault",
    }

    def power(self, on: bool) -> bytes:
        return b"PWR ON\r" if on else b"PWR OFF\r"

    def power_query(self) -> bytes:
        return b"PWR?\r"

    def parse_power(self, reply: str) -> str:
        match = re.search(r"PWR=(\d\d)", reply)
        if not match or match.group(1) not in self._power:
            raise DeviceProtocolError(f"epson: unexpected power reply {reply!r}")
        return self._power[match.group(1)]

    def select_input(self, code: str) -> bytes:
        return f"SOURCE {code}\r".encode()

    def blank(self, on: bool) -> bytes:
        return b"MUTE ON\r" if on else b"MUTE OFF\r"

    def answers(self, command: bytes, reply: str) -> bool:
        text = command.decode().strip()
        if text.endswith("?"):  # a query answers KEY=value, then the prompt
            return reply.strip().startswith(text[:-1] + "=")
        return reply.strip() == ":"  # a set answers the bare prompt

    def check(self, command: bytes, reply: str) -> None:
        if "ERR" in reply:
            raise DeviceProtocolError(f"epson: {command.strip()!r} refused (ERR)")
        if not reply.endswith(":"):
            raise DeviceProtocolError(f"epson: unexpected reply {reply!r}")


class Optoma(CommandSet):
    """`~IDcmd value\\r` (ID 00 = any projector); replies `P` (pass) or `F` (fail); the power query
    `~00124 1` answers `OK1`/`OK0` (query code from Optoma's RS-232 tables; unverified on hardware)."""

    name, baudrate, terminator = "optoma", 9600, b"\r"
    inputs: ClassVar[dict[str, str]] = {"hdmi": "1", "hdmi2": "15", "vga": "5"}

    def power(self, on: bool) -> bytes:
        return f"~0000 {int(on)}\r".encode()

    def power_query(self) -> bytes:
        return b"~00124 1\r"

    def parse_power(self, reply: str) -> str:
        match = re.search(r"OK([01])", reply)
        if not match:
            raise DeviceProtocolError(f"optoma: unexpected power reply {reply!r}")
        return "on" if match.group(1) == "1" else "off"

    def select_input(self, code: str) -> bytes:
        return f"~0012 {code}\r".encode()

    def blank(self, on: bool) -> bytes:
        return f"~0002 {int(on)}\r".encode()

    def answers(self, command: bytes, reply: str) -> bool:
        if command.strip() == self.power_query().strip():
            return reply.strip().startswith("OK")
        return reply.strip() == "P"

    def check(self, command: bytes, reply: str) -> None:
        if reply.strip().startswith("F"):
            raise DeviceProtocolError(f"optoma: {command.strip()!r} refused (F)")
        if not (reply.strip().startswith("P") or reply.strip().startswith("OK")):
            raise DeviceProtocolError(f"optoma: unexpected reply {reply!r}")


COMMAND_SETS: dict[str, type[CommandSet]] = {"benq": BenQ, "epson": Epson, "optoma": Optoma}


class SerialPowerControl(PowerControl):
    """Power, input and blank of a projector on a serial port (`url`: /dev/ttyUSB0, socket://...,
    or simprojector://benq for the simulated one)."""

    @classmethod
    def from_config(cls, device: DeviceConfig) -> SerialPowerControl:
        """The control a projector config's `power` section (a vendor's protocol, url) describes."""
        p = device.power
        return cls(f"{device.name}-power", p.url, p.protocol, p.timeout_s)

    def __init__(self, name: str, url: str, vendor: str, timeout_s: float = 2.0, baudrate: int | None = None) -> None:
        super().__init__(name)
        if vendor not in COMMAND_SETS:
            raise ValueError(f"{name}: unknown projector command set {vendor!r}; known: {', '.join(COMMAND_SETS)}")
        self.commands = COMMAND_SETS[vendor]()
        self.url = url
        self.timeout_s = timeout_s
        self.baudrate = baudrate or self.commands.baudrate
        self._port = None
        self._stale = False  # a reply may still be on its way from a command that timed out
        self.last_reply = ""

    def _do_open(self) -> None:
        import serial

        if SIM_HANDLERS not in serial.protocol_handler_packages:
            serial.protocol_handler_packages.append(SIM_HANDLERS)
        try:
            self._port = serial.serial_for_url(
                self.url, baudrate=self.baudrate, timeout=self.timeout_s, write_timeout=self.timeout_s
            )
        except (serial.SerialException, ValueError) as exc:
            raise DeviceNotFoundError(f"{self.name}: cannot open {self.url}: {exc}") from exc

    def _do_close(self) -> None:
        if self._port is not None:
            with contextlib.suppress(Exception):
                self._do_blank(True)
            self._port.close()
            self._port = None

    def _drain(self) -> None:
        """After a timeout a reply may still be on its way: let it arrive and throw it away."""
        assert self._port is not None
        quiet_s = min(0.5, self.timeout_s)
        previous = self._port.timeout
        self._port.timeout = quiet_s
        try:
            while self._port.read(4096):
                pass
        finally:
            self._port.timeout = previous
        self._stale = False

    def _exchange(self, command: bytes) -> str:
        """Send `command` and return its reply: the first complete reply that answers this command
        (a late reply to an earlier one does not), before the timeout."""
        import serial

        self._require_open()
        assert self._port is not None
        try:
            if self._stale:
                self._drain()
            deadline = time.monotonic() + self.timeout_s
            self._port.reset_input_buffer()
            self._port.write(command)
            while True:
                reply = self._port.read_until(self.commands.terminator)
                if not reply or not reply.endswith(self.commands.terminator):
                    break
                text = self._text(reply)
                if self.commands.is_echo(command, reply):  # serial BenQs echo the command first
                    continue
                self.commands.check(command, text)  # an error reply is for this command: raise
                if self.commands.answers(command, text):
                    self.last_reply = text
                    return text
                if time.monotonic() > deadline:
                    break
        except serial.SerialException as exc:
            raise DeviceDisconnectedError(f"{self.name}: serial port failed: {exc}") from exc
        self._stale = True
        if not reply:
            raise DeviceTimeoutError(f"{self.name}: no reply to {command.strip()!r} within {self.timeout_s:g} s")
        text = self._text(reply)
        if not reply.endswith(self.commands.terminator):
            raise DeviceTimeoutError(f"{self.name}: incomplete reply {text!r} within {self.timeout_s:g} s")
        raise DeviceTimeoutError(
            f"{self.name}: no reply to {command.strip()!r} within {self.timeout_s:g} s "
            f"(only {text!r}, which answers something else)"
        )

    def _text(self, reply: bytes) -> str:
        try:
            return reply.decode("ascii")
        except UnicodeDecodeError:
            self._stale = True
            raise DeviceProtocolError(f"{self.name}: garbled reply {reply!r} (wrong baud rate?)") from None

    def _do_power(self, on: bool) -> None:
        self._exchange(self.commands.power(on))

    def _do_power_state(self) -> str:
        return self.commands.parse_power(self._exchange(self.commands.power_query()))

    def _do_select_input(self, name: str) -> None:
        if name not in self.commands.inputs:
            raise ValueError(f"{self.name}: unknown input {name!r}; known: {', '.join(self.commands.inputs)}")
        self._exchange(self.commands.select_input(self.commands.inputs[name]))

    def _do_blank(self, on: bool) -> None:
        self._exchange(self.commands.blank(on))


def machine_problems(device: DeviceConfig) -> list[str]:
    """A serial port the service user may open, where the `power` url names a device node (slrig doctor)."""
    url = device.power.url if device.power is not None else None
    problem = access_problem(url, "dialout") if url and url.startswith("/dev/") else None
    return [problem] if problem else []
