"""DLPC350/DLPC900 USB HID message framing: one 64-byte report per command here.

    byte 0   flags: bit7 read, bit6 reply wanted, bit5 error (in replies), bits2:0 destination
    byte 1   sequence number, echoed in the reply
    byte 2-3 payload length, little-endian (2 command bytes + data)
    byte 4-5 command, little-endian (CMD3 then CMD2)
    byte 6.. data, little-endian; the report is zero-padded to 64 bytes
A reply is [flags, sequence, length (2 bytes), data...].
"""

from __future__ import annotations

import struct
import time

from drivers.errors import DeviceProtocolError, DeviceTimeoutError
from drivers.usbhid import REPORT_SIZE, HidTransport

FLAG_READ = 0x80
FLAG_REPLY = 0x40
FLAG_ERROR = 0x20
MAX_DATA = REPORT_SIZE - 6


def encode(command: int, data: bytes, sequence: int, read: bool, reply: bool) -> bytes:
    if len(data) > MAX_DATA:
        raise ValueError(f"command 0x{command:04x}: {len(data)} data bytes do not fit one report")
    flags = (FLAG_READ if read else 0) | (FLAG_REPLY if reply else 0)
    header = struct.pack("<BBHH", flags, sequence, len(data) + 2, command)
    return (header + data).ljust(REPORT_SIZE, b"\0")


class DlpcProtocol:
    """Commands and replies over a HID transport, with sequence numbers checked.

    A reply whose sequence number is not the one just sent is a late answer to an earlier
    command: it is dropped, and reading goes on until the right reply or the deadline.
    """

    def __init__(self, transport: HidTransport, name: str, timeout_s: float = 2.0) -> None:
        self._transport = transport
        self.name = name
        self.timeout_s = timeout_s
        self._sequence = 0

    def _next_sequence(self) -> int:
        self._sequence = (self._sequence + 1) & 0xFF
        return self._sequence

    def _exchange(self, command: int, data: bytes, read: bool) -> bytes:
        sequence = self._next_sequence()
        deadline = time.monotonic() + self.timeout_s
        self._transport.write(encode(command, data, sequence, read, reply=True), self.timeout_s)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DeviceTimeoutError(
                    f"{self.name}: no reply to command 0x{command:04x} within {self.timeout_s:g} s"
                )
            report = self._transport.read(remaining)
            if len(report) < 4:
                raise DeviceProtocolError(f"{self.name}: short reply ({len(report)} bytes) to 0x{command:04x}")
            flags, seq, length = struct.unpack_from("<BBH", report)
            if seq != sequence:
                continue  # a late reply to an earlier command
            if flags & FLAG_ERROR:
                raise DeviceProtocolError(f"{self.name}: command 0x{command:04x} failed (error bit in the reply)")
            if length > len(report) - 4:
                raise DeviceProtocolError(f"{self.name}: reply to 0x{command:04x} claims {length} bytes")
            return report[4 : 4 + length]

    def write(self, command: int, data: bytes = b"") -> None:
        """A write the device acknowledges."""
        self._exchange(command, data, read=False)

    def read(self, command: int, length: int, data: bytes = b"") -> bytes:
        """A read of `length` bytes (some reads take parameters in `data`)."""
        payload = self._exchange(command, data, read=True)
        if len(payload) < length:
            raise DeviceProtocolError(
                f"{self.name}: reply to 0x{command:04x} has {len(payload)} bytes, expected {length}"
            )
        return payload[:length]
