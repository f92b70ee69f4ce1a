"""The LightCrafter's pattern LUT as TI's own software writes it. Each expected entry below was
worked out by hand from TI's rules (docs/protocols/dlpc350.md names each rule's source), not taken
from slrig's output: bits 1:0 trigger (0 internal, 1 external or VSYNC-frame start, 3 none), 7:2
pattern, 11:8 bit depth, 14:12 LEDs, 17 insert black, 18 buffer swap; three bytes, little-endian.
And the controller's validation, as the fake models it, flags what TI's validator flags."""

from __future__ import annotations

import pytest

from drivers.dlp.lut import lut_words
from drivers.errors import DeviceProtocolError
from drivers.fakes.dlpc350 import FakeLcr4500
from drivers.sequences import EntryTrigger, PatternSequence, SequenceEntry, TriggerMode
from tests.test_projectors import _lcr

INT, EXT, CONT = EntryTrigger.INTERNAL, EntryTrigger.EXTERNAL, EntryTrigger.CONTINUE


def _entries(patterns: list[int], depth: int, triggers: list[EntryTrigger | None] | None = None) -> tuple:
    triggers = triggers or [None] * len(patterns)
    return tuple(SequenceEntry(p, depth, trigger=t) for p, t in zip(patterns, triggers, strict=True))


GOLDEN = {
    # the first example: VSYNC, each frame's first pattern external (1) with a buffer swap
    "vsync 8-bit": (PatternSequence(_entries([0, 1, 2], 8), 8333, 8333, TriggerMode.VSYNC), "017804 077800 0b7800"),
    "vsync 8-bit, two frames": (
        PatternSequence(_entries([0, 1, 2, 0, 1, 2], 8), 8333, 8333, TriggerMode.VSYNC),
        "017804 077800 0b7800 017804 077800 0b7800",
    ),
    # two 8-bit patterns fill a 60 Hz frame at their 8333 us minimum
    "vsync 8-bit, a frame of two": (
        PatternSequence(_entries([0, 1], 8), 8333, 8333, TriggerMode.VSYNC),
        "017804 077800",
    ),
    "vsync 1-bit": (PatternSequence(_entries([0, 1, 2], 1), 2778, 2778, TriggerMode.VSYNC), "017104 077100 0b7100"),
    # the second example: external, exposure under the period: black after each
    "external 1-bit, short exposure": (
        PatternSequence(_entries([7, 15, 23], 1), 8000, 8333, TriggerMode.EXTERNAL),
        "1d7102 3d7102 5d7102",
    ),
    "external 8-bit": (
        PatternSequence(_entries([0, 1, 2], 8), 8333, 8333, TriggerMode.EXTERNAL),
        "017802 057802 097802",
    ),
    "internal 8-bit": (PatternSequence(_entries([0, 1, 2], 8), 8333, 8333), "007800 047800 087800"),
    "internal 8-bit, short exposure": (PatternSequence(_entries([0, 1, 2], 8), 8000, 8333), "007802 047802 087802"),
    "internal 4-bit": (
        PatternSequence(_entries(list(range(6)), 4), 4500, 4500),
        "007400 047400 087400 0c7400 107400 147400",
    ),
    # one external trigger, then patterns that continue on it
    "external, then continuing": (
        PatternSequence(_entries([0, 1, 2], 8, [EXT, CONT, CONT]), 8333, 8333),
        "017802 077802 0b7802",
    ),
    # black on the entry before an externally triggered one
    "internal, internal, external": (
        PatternSequence(_entries([0, 1, 2], 8, [INT, INT, EXT]), 8333, 8333),
        "007800 047802 097802",
    ),
    "flash, two images": (
        PatternSequence(_entries([0, 1, 2, 0, 1, 2], 8), 8333, 8333, source="flash", flash_images=(5, 2)),
        "007804 047800 087800 007804 047800 087800",
    ),
    # repeating: the last pattern is the one before the externally triggered first
    "external then internal, repeating": (
        PatternSequence(_entries([0, 1], 8, [EXT, INT]), 8333, 8333, repeat=True),
        "017802 047802",
    ),
    "1-bit black (pattern 24)": (PatternSequence(_entries([24], 1), 8333, 8333), "607100"),
    "red only": (PatternSequence((SequenceEntry(0, 8, leds="r"),), 8333, 8333), "001800"),
}


@pytest.mark.parametrize("name", list(GOLDEN))
def test_the_lut_is_what_tis_software_writes(name: str) -> None:
    sequence, expected = GOLDEN[name]
    assert " ".join(word.hex() for word in lut_words(sequence)) == expected


@pytest.mark.parametrize(
    "name", ["vsync 8-bit, a frame of two", "external 1-bit, short exposure", "external, then continuing"]
)
def test_the_driver_sends_those_bytes_and_the_controller_takes_them(name: str) -> None:
    sequence, expected = GOLDEN[name]
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    try:
        projector.load_sequence(sequence)  # validated: a refusal would raise
        assert " ".join(word.to_bytes(3, "little").hex() for word in fake.lut_entries) == expected
    finally:
        projector.close()


@pytest.mark.parametrize(
    ("entries", "exposure", "flagged"),
    [
        # no black before an externally triggered pattern: TI's bit 3
        ((SequenceEntry(0, 8, insert_black=False), SequenceEntry(1, 8, trigger=EXT)), 8333, "post vector"),
        # no black after a pattern shorter than its period: bit 3 too
        ((SequenceEntry(0, 8, insert_black=False),), 8000, "post vector"),
        # a 1-bit pattern shorter than its minimum (235 us): bit 0
        ((SequenceEntry(0, 1),), 200, "exposure or frame period invalid"),
    ],
)
def test_the_controller_flags_what_tis_validator_flags_and_the_driver_refuses_it(
    entries: tuple[SequenceEntry, ...], exposure: int, flagged: str
) -> None:
    projector = _lcr(FakeLcr4500())
    projector.open()
    try:
        with pytest.raises(DeviceProtocolError, match=flagged):
            projector.load_sequence(PatternSequence(entries, exposure, 8333))
    finally:
        projector.close()


def test_a_video_port_sequence_counts_its_frames_as_tis_gui_does() -> None:
    """PAT_CONFIG's last byte, images - 1: TI's GUI writes the number of buffer swaps there for
    the video port too (two frames of two 8-bit patterns: 1)."""
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    try:
        sequence = PatternSequence(_entries([0, 1, 0, 1], 8), 8333, 8333, TriggerMode.VSYNC)
        projector.load_sequence(sequence)
        assert fake.pattern_config == bytes([3, 0, 3, 1])
    finally:
        projector.close()


def test_standby_goes_through_video_mode_as_tis_gui_does() -> None:
    from drivers.dlp.commands import COMMANDS

    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    try:
        projector.load_sequence(PatternSequence(_entries([0, 1], 8), 8333, 8333, TriggerMode.EXTERNAL))
        start = len(fake.log)
        projector.standby()
        writes = [(COMMANDS[code].name, data) for kind, code, data in fake.log[start:] if kind == "w"]
        names = [name for name, _ in writes]
        assert names.index("DISP_MODE") < names.index("POWER_CONTROL")
        assert dict(writes)["DISP_MODE"] == bytes([0]) and dict(writes)["POWER_CONTROL"] == bytes([1])
    finally:
        projector.close()


def test_patterns_that_share_an_exposure() -> None:
    """The second and third 1-bit patterns lit within the first's exposure: trigger 3 and
    trigger-out-previous (bit 19); no black inside the shared exposure (TI's GUI refuses black on
    an entry the next one shares), black after the group's last (the SDK's rule for a pattern not
    internally triggered, as on the blue third of its RGB patterns)."""
    entries = (
        SequenceEntry(0, 1),
        SequenceEntry(1, 1, shares_exposure=True),
        SequenceEntry(2, 1, shares_exposure=True),
    )
    sequence = PatternSequence(entries, 8333, 8333)
    assert " ".join(word.hex() for word in lut_words(sequence)) == "007100 077108 0b710a"
    forced = (SequenceEntry(0, 1, insert_black=True), *entries[1:])  # black asked for anyway: bit 2
    projector = _lcr(FakeLcr4500())
    projector.open()
    try:
        projector.load_sequence(sequence)
        with pytest.raises(DeviceProtocolError, match="overlapping black"):
            projector.load_sequence(PatternSequence(forced, 8333, 8333))
    finally:
        projector.close()


@pytest.mark.parametrize(
    ("sequence", "refusal"),
    [
        (PatternSequence(_entries([0, 1], 8, [CONT, INT]), 8333, 8333), "first pattern must have a trigger"),
        (PatternSequence((SequenceEntry(0, 1, shares_exposure=True),), 8333, 8333), "first pattern must have"),
        (PatternSequence(_entries([0, 1], 8, [None, EXT]), 8333, 8333, TriggerMode.VSYNC), "follows its frame"),
    ],
)
def test_what_tis_software_refuses_to_write_is_refused(sequence: PatternSequence, refusal: str) -> None:
    with pytest.raises(ValueError, match=refusal):
        lut_words(sequence)


def test_a_repeating_sequence_needs_black_before_its_triggered_first_pattern() -> None:
    projector = _lcr(FakeLcr4500())
    projector.open()
    try:
        entries = (SequenceEntry(0, 8, trigger=EXT), SequenceEntry(1, 8, trigger=INT))
        projector.load_sequence(PatternSequence(entries, 8333, 8333))  # once through: nothing before the first
        projector.load_sequence(PatternSequence(entries, 8333, 8333, repeat=True))  # the rule puts black on the last
        forced = (entries[0], SequenceEntry(1, 8, trigger=INT, insert_black=False))
        with pytest.raises(DeviceProtocolError, match="post vector"):
            projector.load_sequence(PatternSequence(forced, 8333, 8333, repeat=True))
    finally:
        projector.close()
