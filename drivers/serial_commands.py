"""The serial projector frames slrig sends, as data: per vendor and operation, the frame and the
values it takes, with the document each comes from. The simulated projector
(drivers.fakes.serial_handlers) refuses any frame not in this table as its vendor refuses one, and
tests/test_protocol_tables.py checks every frame the command sets build against it.
"""

from __future__ import annotations

from dataclasses import dataclass

BENQ = "BenQ RS232 command table (BenQ MX613ST manual p. 57, SP920); ../shared/reference/hardware.md 3.3"
EPSON = "Epson ESC/VP21 user's guide (power, source, mute); ../shared/reference/hardware.md 3.2"
OPTOMA = "Optoma RS-232 tables (Pro160s, EX785 manuals); ../shared/reference/hardware.md 3.4"


@dataclass(frozen=True)
class SerialCommand:
    vendor: str
    operation: str  # power, power?, input, blank
    frame: str  # the bytes sent, with {value} where a value goes
    values: tuple[str, ...]  # what {value} may be ("" for a frame without one)
    source: str

    def encodings(self) -> list[bytes]:
        return [self.frame.format(value=value).encode("ascii") for value in self.values]


SERIAL_COMMANDS = (
    SerialCommand("benq", "power", "\r*pow={value}#\r", ("on", "off"), BENQ),
    SerialCommand("benq", "power?", "\r*pow=?#\r", ("",), BENQ),
    SerialCommand("benq", "input", "\r*sour={value}#\r", ("hdmi", "hdmi2", "RGB"), BENQ),
    SerialCommand("benq", "blank", "\r*blank={value}#\r", ("on", "off"), BENQ),
    SerialCommand("epson", "power", "PWR {value}\r", ("ON", "OFF"), EPSON),
    SerialCommand("epson", "power?", "PWR?\r", ("",), EPSON),
    SerialCommand("epson", "input", "SOURCE {value}\r", ("30", "A0", "10", "40"), EPSON),
    SerialCommand("epson", "blank", "MUTE {value}\r", ("ON", "OFF"), EPSON),
    SerialCommand("optoma", "power", "~0000 {value}\r", ("1", "0"), OPTOMA),
    SerialCommand("optoma", "power?", "~00124 1\r", ("",), f"{OPTOMA} (the power query code is unverified)"),
    SerialCommand("optoma", "input", "~0012 {value}\r", ("1", "15", "5"), OPTOMA),
    SerialCommand("optoma", "blank", "~0002 {value}\r", ("1", "0"), OPTOMA),
)


def frames(vendor: str) -> set[bytes]:
    """Every frame of `vendor` the table allows, as sent."""
    return {frame for c in SERIAL_COMMANDS if c.vendor == vendor for frame in c.encodings()}
