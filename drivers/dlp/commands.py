"""The DLPC350 commands slrig sends, as data: code, how many data bytes a write carries and a read
returns, the bits the document reserves (or the values it allows), and where each comes from.

Sources:
- CmdList: TI's DLPC350 API, `dlpc350_api.cpp`, the table `CmdList` of {CMD2, CMD3, length}
  (as vendored in jakobwilm/slstudio, src/projector/LC4500API). `length` is the data length of a
  write; 0 there means the command is only read or its length varies (MBOX_DATA).
- API: the same file's function that builds the command (named per entry) for field layouts and
  read lengths.
- Layout notes are summarised in ../shared/reference/hardware.md, section 2.1.

The protocol fake (drivers.fakes.dlpc350) refuses with the error bit what this table refuses, and
tests/test_dlpc350_commands.py encodes every report the driver sends from this table, independently
of the driver's encoder.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Command:
    name: str
    code: int  # CMD2 << 8 | CMD3; sent little-endian (CMD3 first)
    write_bytes: int | range | None  # data bytes of a write (a range where it varies); None: not written
    read_bytes: int | None  # data bytes a read returns; None: not read
    source: str
    reserved: bytes = b""  # per data byte of a write: bits that must be 0
    allowed: dict[int, frozenset[int]] = field(default_factory=dict)  # data byte -> values a write may hold

    def refuses(self, data: bytes) -> str | None:
        """Why the document refuses this write's data, or None."""
        if self.write_bytes is None:
            return f"{self.name} is not written"
        fits = len(data) in self.write_bytes if isinstance(self.write_bytes, range) else len(data) == self.write_bytes
        if not fits:
            return f"{self.name} carries {_lengths(self.write_bytes)} data bytes, not {len(data)}"
        for index, (value, mask) in enumerate(zip(data, self.reserved, strict=False)):
            if value & mask:
                return f"{self.name} byte {index}: reserved bits 0x{value & mask:02x} set"
        for index, values in self.allowed.items():
            if data[index] not in values:
                return f"{self.name} byte {index}: {data[index]} is not one of {sorted(values)}"
        return None


def _lengths(expected: int | range) -> str:
    return f"{expected.start} to {expected.stop - 1}" if isinstance(expected, range) else str(expected)


_LIST = "CmdList"
COMMANDS = {
    c.code: c
    for c in (
        Command("POWER_CONTROL", 0x0200, 1, None, f"{_LIST}; DLPC350_SetPowerMode: 0 normal, 1 standby", b"\xfe"),
        Command("GET_VERSION", 0x0205, None, 16, f"{_LIST} (read); DLPC350_GetVersion: 4 x uint32"),
        Command(
            "LED_ENABLE", 0x1A07, 1, 1, f"{_LIST}; DLPC350_SetLedEnables: bit3 sequencer, bits 2:0 B, G, R", b"\xf0"
        ),
        Command("STATUS_HW", 0x1A0A, None, 1, f"{_LIST} (read); DLPC350_GetStatus"),
        Command("STATUS_SYS", 0x1A0B, None, 1, f"{_LIST} (read); DLPC350_GetStatus"),
        Command("STATUS_MAIN", 0x1A0C, None, 1, f"{_LIST} (read); DLPC350_GetStatus"),
        Command("LUT_VALID", 0x1A1A, 1, 1, f"{_LIST}; DLPC350_StartPatLutValidate writes one byte 0x00", b"\xff"),
        Command("DISP_MODE", 0x1A1B, 1, 1, f"{_LIST}; DLPC350_SetMode: 0 video, 1 pattern", b"\xfe"),
        Command(
            "TRIG_OUT1_CTL", 0x1A1D, 3, None, f"{_LIST}; DLPC350_SetTrigOutConfig: invert, rising, falling", b"\xfe"
        ),
        Command(
            "PAT_DISP_MODE",
            0x1A22,
            1,
            None,
            f"{_LIST}; DLPC350_SetPatternDisplayMode: 0 video port, 3 flash",
            allowed={0: frozenset({0, 3})},
        ),
        Command(
            "PAT_TRIG_MODE",
            0x1A23,
            1,
            None,
            f"{_LIST}; DLPC350_SetPatternTriggerMode: modes 0-4",
            allowed={0: frozenset(range(5))},
        ),
        Command(
            "PAT_START_STOP",
            0x1A24,
            1,
            1,
            f"{_LIST}; DLPC350_PatternDisplay: 0 stop, 1 pause, 2 start",
            allowed={0: frozenset({0, 1, 2})},
        ),
        Command("PAT_EXPO_PRD", 0x1A29, 8, None, f"{_LIST}; DLPC350_SetExposure_FramePeriod: 2 x uint32 us"),
        Command(
            "PAT_CONFIG",
            0x1A31,
            4,
            None,
            f"{_LIST}; DLPC350_SetPatternConfig: entries-1, repeat, trig2-1, images-1",
            b"\x00\xfe\x00\x00",
        ),
        Command("MBOX_ADDRESS", 0x1A32, 1, None, f"{_LIST}; DLPC350_SetPatternConfig (mailbox offset 0-127)", b"\x80"),
        Command(
            "MBOX_CONTROL",
            0x1A33,
            1,
            None,
            f"{_LIST}; DLPC350_OpenMailbox: 0 close, 1 image LUT, 2 pattern LUT, 3 variable exposure",
            allowed={0: frozenset(range(4))},
        ),
        Command(
            "MBOX_DATA",
            0x1A34,
            range(1, 65),
            None,
            f"{_LIST} (length 0: varies with the open mailbox; see PATTERN_LUT_ENTRY and IMAGE_LUT)",
        ),
        Command("NUM_IMAGE_IN_FLASH", 0x1A42, None, 1, f"{_LIST} (read); DLPC350_GetNumImagesInFlash"),
        Command(
            "MBOX_EXP_DATA",
            0x1A3E,
            12,
            None,
            f"{_LIST}; DLPC350_SendVarExpPatLut: LUT word as uint32, exposure, period (uint32 us)",
            b"\x00\x00\xf0\xff",
        ),
        Command("MBOX_EXP_ADDRESS", 0x1A3F, 2, None, f"{_LIST}; DLPC350_SetVarExpMboxAddr: uint16 0-1823", b"\x00\xf8"),
        Command(
            "EXP_PAT_CONFIG",
            0x1A40,
            6,
            None,
            f"{_LIST}; DLPC350_SetVarExpPatternConfig: entries-1, trig2-1 (uint16), images-1, repeat",
            b"\x00\xf8\x00\x00\x00\xfe",
        ),
    )
}
# MBOX_DATA with mailbox 2 open: one pattern LUT entry (DLPC350_AddToPatLut; DLPC350 Programmer's
# Guide table 2-65; bits 23:20 reserved). TI's SendPatLut writes every entry in one message from
# address 0; slrig writes each entry at its address, as pycrafter4500 does.
PATTERN_LUT_ENTRY = Command("MBOX_DATA (pattern LUT)", 0x1A34, 3, None, "DLPC350_SendPatLut", b"\x00\x00\xf0")
# MBOX_DATA with mailbox 1 open: the image indices, one byte each, all in one write; exactly two
# entries are written in reverse order (DLPC350_SendImageLut, "special case of 2 entries")
IMAGE_LUT = Command("MBOX_DATA (image LUT)", 0x1A34, range(1, 65), None, "DLPC350_SendImageLut")
