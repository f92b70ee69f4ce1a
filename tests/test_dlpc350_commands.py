"""The LightCrafter 4500 driver checked against the DLPC350 command table (drivers.dlp.commands),
which is written from TI's command list, not from the driver: every report the driver sends is
encoded again here from the table's layout, and the protocol fake refuses what the table refuses."""

from __future__ import annotations

import struct

import pytest

from drivers.dlp import lcr4500
from drivers.dlp.commands import COMMANDS, PATTERN_LUT_ENTRY
from drivers.dlp.lut import image_lut_bytes
from drivers.fakes.dlpc350 import FakeLcr4500
from drivers.sequences import PatternSequence, SequenceEntry, TriggerMode
from tests.test_projectors import _lcr

# three 8-bit patterns in one video frame of a 30 Hz input (each needs 8333 us)
VSYNC_8BIT = PatternSequence(tuple(SequenceEntry(i, 8) for i in range(3)), 8333, 8333, TriggerMode.VSYNC)


def _golden(reports: list[bytes], images: int = 0) -> list[bytes]:
    """The reports as the table says they must be: flags (read or write, reply wanted), the
    sequence number, length = 2 + the table's data length, the command CMD3 first, the data, zeros
    to 64. Mailbox data is a pattern LUT entry with mailbox 2 open, `images` indices with 1 open."""
    golden, mailbox = [], 0
    for report in reports:
        flags, sequence, _, code = struct.unpack_from("<BBHH", report)
        command, read = COMMANDS[code], bool(flags & 0x80)
        size = 0 if read else command.write_bytes
        if code == lcr4500.CMD_MBOX_DATA and not read:
            size = PATTERN_LUT_ENTRY.write_bytes if mailbox == 2 else images
        assert isinstance(size, int), f"{command.name}: the table gives no length for this write"
        data = report[6 : 6 + size]
        if code == lcr4500.CMD_MBOX_CONTROL and not read:
            mailbox = data[0]
        head = bytes([0xC0 if read else 0x40, sequence]) + (2 + size).to_bytes(2, "little")
        golden.append((head + code.to_bytes(2, "little") + data).ljust(64, b"\0"))
    return golden


def test_every_command_the_driver_names_is_in_the_table_with_its_code() -> None:
    named = {name: value for name, value in vars(lcr4500).items() if name.startswith("CMD_")}
    assert named and all(code in COMMANDS for code in named.values()), sorted(
        name for name, code in named.items() if code not in COMMANDS
    )


def test_a_3_pattern_8_bit_vsync_sequence_is_every_report_the_document_lays_out() -> None:
    fake = FakeLcr4500(video_period_us=33334)
    projector = _lcr(fake)
    projector.open()
    projector.configure_trigger_out(rising_delay_ns=0.0)
    first = len(fake.reports)
    projector.load_sequence(VSYNC_8BIT)
    projector.start_sequence()
    sent = fake.reports[first:]
    assert not fake.refused
    assert fake.reports == _golden(fake.reports)
    writes = [(COMMANDS[code].name, data) for kind, code, data in fake.log[-len(sent) :] if kind == "w"]
    names = [name for name, _ in writes]
    # the document's order: stop, pattern mode, source, configuration, trigger mode, exposure and
    # period, the LUT through the mailbox, close, validate, start; each once
    assert names[: names.index("MBOX_CONTROL")] == [
        "PAT_START_STOP",
        "DISP_MODE",
        "PAT_DISP_MODE",
        "PAT_CONFIG",
        "PAT_TRIG_MODE",
        "PAT_EXPO_PRD",
    ]
    lut = names[names.index("MBOX_CONTROL") : names.index("LUT_VALID")]
    assert lut == ["MBOX_CONTROL", *["MBOX_ADDRESS", "MBOX_DATA"] * 3, "MBOX_CONTROL"]
    assert names[names.index("LUT_VALID") :][0] == "LUT_VALID" and names.count("LUT_VALID") == 1
    assert ("PAT_START_STOP", bytes([2])) in writes[names.index("LUT_VALID") :]
    assert dict(writes)["PAT_CONFIG"] == bytes([2, 0, 2, 0])  # 3 entries, no repeat, 3 for TRIG_OUT2, 1 image
    assert dict(writes)["PAT_TRIG_MODE"] == bytes([0])  # VSYNC
    assert dict(writes)["LUT_VALID"] == bytes([0])  # one data byte: sent with none before this table
    assert [(w >> 2) & 0x3F for w in fake.lut_entries] == [0, 1, 2] and all(
        (w >> 8) & 0xF == 8 for w in fake.lut_entries
    )
    projector.close()


def _send(fake: FakeLcr4500, code: int, data: bytes) -> None:
    fake.write(0x01, (struct.pack("<BBHH", 0x40, 9, 2 + len(data), code) + data).ljust(64, b"\0"), 1000)


def test_a_pattern_lut_entry_with_reserved_bits_is_refused() -> None:
    fake = FakeLcr4500()
    _send(fake, 0x1A33, b"\x02")  # the pattern LUT's mailbox
    fake.read(0x81, 64, 1000)
    _send(fake, 0x1A34, b"\x00\x00\x10")  # bit 20 of the entry
    assert fake.read(0x81, 64, 1000)[0] & 0x20 and "reserved bits" in fake.refused[-1]
    _send(fake, 0x1A34, b"\x00\x00")  # two bytes: an entry is three
    assert fake.read(0x81, 64, 1000)[0] & 0x20 and "carries 3 data bytes, not 2" in fake.refused[-1]
    assert fake.lut == {}


@pytest.mark.parametrize(
    ("code", "data", "reason"),
    [
        (0x1A1A, b"", "carries 1 data bytes, not 0"),  # LUT_VALID as slrig sent it before
        (0x1A29, b"\x00" * 4, "carries 8 data bytes, not 4"),  # exposure without the period
        (0x1A1B, b"\x02", "reserved bits"),  # display mode 2 does not exist on a DLPC350
        (0x1A34, b"", "carries 1 to 64 data bytes, not 0"),  # mailbox data of nothing
        (0x1A22, b"\x01", "is not one of [0, 3]"),  # pattern source 1
        (0x1A0C, b"\x00", "is not written"),  # a status is read, never written
        (0x1234, b"", "unknown command"),
    ],
)
def test_the_fake_refuses_what_the_document_refuses(code: int, data: bytes, reason: str) -> None:
    fake = FakeLcr4500()
    _send(fake, code, data)
    reply = fake.read(0x81, 64, 1000)
    assert reply[0] & 0x20 and reply[1] == 9  # the error bit, for this sequence number
    assert reason in fake.refused[-1]
    assert fake.display_mode == 0 and fake.exposure_us == 0  # nothing changed


def test_each_pattern_chooses_its_leds_black_after_it_and_its_buffer_swap() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    entries = (
        SequenceEntry(0, 8, leds="r"),
        SequenceEntry(1, 8, leds="gb", insert_black=True),
        SequenceEntry(2, 8, leds="rgb", buffer_swap=True),
    )
    projector.load_sequence(PatternSequence(entries, 8333, 8333, TriggerMode.INTERNAL))
    words = fake.lut_entries
    assert [(w >> 12) & 0b111 for w in words] == [0b001, 0b110, 0b111]  # bit 0 red, 1 green, 2 blue
    assert [(w >> 17) & 1 for w in words] == [0, 1, 0] and [(w >> 18) & 1 for w in words] == [0, 0, 1]
    assert not fake.refused
    with pytest.raises(ValueError, match="a mix of 'r', 'g' and 'b'"):
        projector.load_sequence(PatternSequence((SequenceEntry(0, 8, leds="w"),), 8333, 8333))
    projector.close()


@pytest.mark.parametrize(("pattern", "depth", "last"), [(3, 8, 2), (25, 1, 24), (12, 2, 11), (4, 5, 3), (3, 7, 2)])
def test_a_pattern_number_beyond_its_bit_depth_is_refused_naming_the_rule(pattern: int, depth: int, last: int) -> None:
    projector = _lcr(FakeLcr4500())
    projector.open()
    with pytest.raises(ValueError, match=rf"outside 0\.\.{last} for {depth}-bit patterns"):
        projector.load_sequence(PatternSequence((SequenceEntry(pattern, depth),), 8333, 8333))
    projector.close()


def test_standby_parks_the_controller_dark_and_wake_needs_a_new_sequence() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    projector.load_sequence(PatternSequence((SequenceEntry(0, 8),), 8333, 8333))
    projector.start_sequence()
    assert fake.running and not fake.dark
    projector.standby()
    assert fake.standby and fake.dark and not fake.running
    assert [(COMMANDS[c].name, d) for k, c, d in fake.log if k == "w"][-1] == ("POWER_CONTROL", bytes([1]))
    projector.wake()
    assert not fake.standby and fake.dark  # awake, still dark
    projector.load_sequence(PatternSequence((SequenceEntry(0, 8),), 8333, 8333))
    projector.start_sequence()
    assert fake.running and not fake.refused
    projector.close()


def test_a_24_pattern_1_bit_flash_sequence_with_its_image_table() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    entries = tuple(SequenceEntry(plane, 1) for plane in range(24)) * 2  # 24 planes of image 5, then of image 2
    sequence = PatternSequence(entries, 2000, 2500, TriggerMode.EXTERNAL, source="flash", flash_images=(5, 2))
    first = len(fake.reports)
    projector.load_sequence(sequence)
    projector.start_sequence()
    assert not fake.refused and fake.running
    assert fake.reports[first:] == _golden(fake.reports[first:], images=2)
    writes = [(COMMANDS[c].name, d) for k, c, d in fake.log[-(len(fake.reports) - first) :] if k == "w"]
    names = [name for name, _ in writes]
    assert dict(writes)["PAT_DISP_MODE"] == bytes([3]) and dict(writes)["PAT_CONFIG"] == bytes([47, 0, 47, 1])
    image_table = names.index("MBOX_CONTROL", names.index("MBOX_CONTROL") + 1)  # after the pattern LUT closes
    assert writes[image_table + 1 : image_table + 5] == [
        ("MBOX_CONTROL", bytes([1])),
        ("MBOX_ADDRESS", bytes([0])),
        ("MBOX_DATA", bytes([2, 5])),  # two entries go backwards (TI DLPC350_SendImageLut)
        ("MBOX_CONTROL", bytes([0])),
    ]
    assert fake.image_lut == [5, 2]  # as the firmware reads them: image 5 first
    words = fake.lut_entries
    assert [(w >> 2) & 0x3F for w in words] == list(range(24)) * 2 and all((w >> 8) & 0xF == 1 for w in words)
    assert [i for i, w in enumerate(words) if w >> 18 & 1] == [0, 24]  # each image's first plane swaps to it
    assert all(w & 0x3 == 1 for w in words)  # external trigger
    with pytest.raises(ValueError, match=r"the flash holds images 0..7; \[9\] are not there"):
        projector.load_sequence(PatternSequence(entries[:24], 2000, 2500, source="flash", flash_images=(9,)))
    with pytest.raises(ValueError, match="names 1 to 64 stored images"):
        projector.load_sequence(PatternSequence(entries[:24], 2000, 2500, source="flash"))
    projector.close()


@pytest.mark.parametrize(("images", "written"), [((5,), b"\x05"), ((5, 2), b"\x02\x05"), ((5, 2, 7), b"\x05\x02\x07")])
def test_only_a_two_entry_image_table_is_written_backwards(images: tuple[int, ...], written: bytes) -> None:
    assert image_lut_bytes(images) == written


def test_patterns_with_their_own_exposure_use_the_variable_exposure_lut() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    entries = tuple(SequenceEntry(i, 8, exposure_us=e, period_us=e) for i, e in enumerate((8333, 10000, 12000)))
    first = len(fake.reports)
    projector.load_sequence(PatternSequence(entries, 8333, 8333, TriggerMode.EXTERNAL))
    projector.start_sequence()
    assert not fake.refused and fake.running
    assert fake.reports[first:] == _golden(fake.reports[first:])
    writes = [(COMMANDS[c].name, d) for k, c, d in fake.log[-(len(fake.reports) - first) :] if k == "w"]
    names = [name for name, _ in writes]
    assert dict(writes)["PAT_TRIG_MODE"] == bytes([3])  # variable exposure, internal or external trigger
    assert "PAT_CONFIG" not in names and "PAT_EXPO_PRD" not in names  # their variable-exposure forms instead
    assert dict(writes)["EXP_PAT_CONFIG"] == bytes([2, 0, 2, 0, 0, 0])  # 3 entries, 3 per TRIG_OUT_2, 1 image, once
    data = [d for name, d in writes if name == "MBOX_EXP_DATA"]
    assert [struct.unpack("<III", d)[1:] for d in data] == [(8333, 8333), (10000, 10000), (12000, 12000)]
    assert fake.timings() == [(8333, 8333), (10000, 10000), (12000, 12000)]
    assert [(w >> 2) & 0x3F for w in fake.lut_entries] == [0, 1, 2]
    with pytest.raises(ValueError, match="pattern 1: exposure 9900 us must equal the period 10000 us"):
        bad = (entries[0], SequenceEntry(1, 8, exposure_us=9900, period_us=10000))
        projector.load_sequence(PatternSequence(bad, 8333, 8333, TriggerMode.EXTERNAL))
    projector.close()


def test_alternating_pairs_are_trigger_mode_2_with_an_external_trigger() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    entries = tuple(SequenceEntry(i, 8) for i in range(2)) * 2
    projector.load_sequence(PatternSequence(entries, 8333, 8333, TriggerMode.EXTERNAL, alternate_pairs=True))
    assert fake.trigger_mode == 2 and not fake.refused
    assert all(w & 0x3 == 1 for w in fake.lut_entries)  # each pattern waits for its trigger
    for trigger, count in ((TriggerMode.INTERNAL, 4), (TriggerMode.EXTERNAL, 3)):
        with pytest.raises(ValueError, match="alternating pairs"):
            projector.load_sequence(PatternSequence(entries[:count], 8333, 8333, trigger, alternate_pairs=True))
    projector.close()
