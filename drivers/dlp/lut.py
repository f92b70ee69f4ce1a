"""The DLPC350 pattern LUT: entries packed as TI's DLPC350_AddToPatLut packs them (DLPC350
Programmer's Guide table 2-65), the words of a whole sequence by TI's own rules, and the
image-index table. Each rule names its source; docs/protocols/dlpc350.md lists them all.

Sources (public copies of TI's code; read for facts):
- GUI: TI's LightCrafter 4500 Control Software, mainwindow.cpp (as vendored in
  ethz-asl/lightcrafter_4500_gui), on_pushButton_PatSeqAddPatToLut_clicked.
- SDK: TI's DLP ALC LightCrafter SDK, lcr4500.cpp, LCr4500::CreateSendStartSequenceLut (as in
  jiawenxue1004/DLP-ALC-LIGHTCRAFTER-SDK-for-Ubuntu).
- API: TI's DLPC350 API, dlpc350_api.cpp, DLPC350_AddToPatLut and its comments.
"""

from __future__ import annotations

import struct

from drivers.sequences import EntryTrigger, PatternSequence, SequenceEntry, TriggerMode

# LUT bits 1:0 (API, DLPC350_AddToPatLut's comment): 0 internal, 1 external positive, 2 external
# negative, 3 no input trigger (continue from the previous; the pattern keeps its full exposure).
LUT_TRIGGER_INTERNAL, LUT_TRIGGER_EXTERNAL, LUT_TRIGGER_CONTINUE = 0, 1, 3
_TRIGGERS = {
    EntryTrigger.INTERNAL: LUT_TRIGGER_INTERNAL,
    EntryTrigger.EXTERNAL: LUT_TRIGGER_EXTERNAL,
    EntryTrigger.CONTINUE: LUT_TRIGGER_CONTINUE,
}
LED_BITS = {"r": 0b001, "g": 0b010, "b": 0b100}  # LUT bits 14:12 (API, DLPC350_AddToPatLut)
# The shortest exposure per bit depth 1..8, us (GUI min_pat_exposure; SDK Exposure::MININUM).
MIN_EXPOSURE_US = (235, 700, 1570, 1700, 2000, 2500, 4500, 8333)
BLACK_PATTERN = 24  # a 1-bit pattern number showing black (SDK lcr4500.hpp Mono_1BPP::BLACK; the GUI accepts it)


def patterns_of_depth(bit_depth: int) -> int:
    """How many pattern numbers a bit depth has (GUI .ini loader; SDK lcr4500.hpp): 24 // depth,
    but 5-bit 4 and 7-bit 3 (stored at 6- and 8-plane slots), and 1-bit 25 (24: black)."""
    return {1: BLACK_PATTERN + 1, 5: 4, 7: 3}.get(bit_depth, 24 // bit_depth)


def lut_entry(
    pattern: int,
    bit_depth: int,
    trigger: int,
    invert: bool = False,
    led: int = 0b111,
    buffer_swap: bool = False,
    insert_black: bool = False,
    trigger_out_previous: bool = False,
) -> bytes:
    """The 24-bit pattern LUT word (little-endian): trigger 1:0, pattern 7:2, bit depth 11:8,
    LEDs 14:12, invert 16, insert black 17, buffer swap 18, trigger-out-previous 19 (the exposure
    shared with the previous pattern) (API, DLPC350_AddToPatLut); ValueError names the rule broken."""
    if not 1 <= bit_depth <= 8:
        raise ValueError(f"bit depth {bit_depth} is outside 1..8 (LUT bits 11:8)")
    count = patterns_of_depth(bit_depth)
    if not 0 <= pattern < count:
        raise ValueError(
            f"pattern number {pattern} is outside 0..{count - 1} for {bit_depth}-bit patterns"
            + (f" ({BLACK_PATTERN} is black)" if bit_depth == 1 else "")
        )
    if not 0 <= led <= 0b111:
        raise ValueError(f"LED selection {led:#b} is not a mix of red, green and blue (LUT bits 14:12)")
    word = trigger | (pattern << 2) | (bit_depth << 8) | (led << 12) | (int(invert) << 16)
    word |= (int(insert_black) << 17) | (int(buffer_swap) << 18) | (int(trigger_out_previous) << 19)
    return word.to_bytes(3, "little")


def image_lut_bytes(images: tuple[int, ...]) -> bytes:
    """The image-index table as written: TI's DLPC350_SendImageLut sends exactly two entries in
    reverse order (the firmware reads a two-entry table backwards), any other count in order."""
    return bytes(images[::-1] if len(images) == 2 else images)


def leds_of(entry: SequenceEntry) -> int:
    """LUT LED bits of an entry's "rgb" mix; ValueError for a letter that is not an LED."""
    unknown = set(entry.leds) - set(LED_BITS)
    if unknown or not entry.leds:
        raise ValueError(f"LEDs {entry.leds!r}: a mix of 'r', 'g' and 'b'")
    return sum(LED_BITS[c] for c in set(entry.leds))


def lut_words(sequence: PatternSequence) -> list[bytes]:
    """LUT words of a sequence, by TI's rules (see entry_triggers, buffer_swaps, black_after);
    ValueError for a first pattern with no trigger of its own (TI's GUI: "First Item must be
    triggered")."""
    swaps = buffer_swaps(sequence)
    triggers = entry_triggers(sequence, swaps)
    if triggers and triggers[0] == LUT_TRIGGER_CONTINUE:
        raise ValueError("the first pattern must have a trigger of its own (not continue, not a shared exposure)")
    black = black_after(sequence, triggers)
    return [
        lut_entry(e.pattern, e.bit_depth, t, e.invert, leds_of(e), swap, b, e.shares_exposure)
        for e, t, swap, b in zip(sequence.entries, triggers, swaps, black, strict=True)
    ]


def _frame_starts(sequence: PatternSequence) -> list[bool]:
    """Which entries begin a video frame or flash image: the first, and each whose pattern number
    is not above the previous one's (8-bit: green 0, red 1, blue 2). TI's GUI takes the frame index
    from its user; slrig's sequences number patterns within a frame from 0."""
    starts, previous = [], -1
    for entry in sequence.entries:
        starts.append(entry.pattern <= previous or not starts)
        previous = entry.pattern
    return starts


def entry_triggers(sequence: PatternSequence, swaps: list[bool]) -> list[int]:
    """Each entry's LUT trigger type.
    - VSYNC (video port): an entry that swaps to a new frame 1 (external positive), the rest 3 (no
      trigger): GUI on_pushButton_PatSeqAddPatToLut_clicked, "In streaming mode, first item has to
      be triggered by vsync" (trigger 1 exactly where bufSwap); DLPU010 section 4.2's example words
      0x062101, 0x021107 (quoted on TI E2E thread 311314). An entry cannot name its own here.
    - internal or external: 0 or 1 for every entry (GUI: the trigger combo box; SDK: per pattern).
    - an entry's own trigger (SequenceEntry.trigger), where given (SDK: per pattern; GUI: a
      trigger removed from an item makes it 3); an entry that shares the previous one's exposure,
      3 (SDK: the green and blue thirds of an RGB pattern, trigger NONE)."""
    out = []
    for entry, swap in zip(sequence.entries, swaps, strict=True):
        if sequence.trigger is TriggerMode.VSYNC:
            if entry.trigger is not None or entry.shares_exposure:
                raise ValueError(
                    "under VSYNC each pattern's trigger follows its frame: no trigger or shared exposure of its own"
                )
            out.append(LUT_TRIGGER_EXTERNAL if swap else LUT_TRIGGER_CONTINUE)
        elif entry.trigger is not None:
            out.append(_TRIGGERS[entry.trigger])
        elif entry.shares_exposure:
            out.append(LUT_TRIGGER_CONTINUE)
        else:
            out.append(LUT_TRIGGER_EXTERNAL if sequence.trigger is TriggerMode.EXTERNAL else LUT_TRIGGER_INTERNAL)
    return out


def buffer_swaps(sequence: PatternSequence) -> list[bool]:
    """Whether each entry swaps the frame buffer first: under VSYNC or from flash, the first entry
    and each that starts a new video frame or flash image (GUI: bufSwap = frame index changed, true
    on the first item; SDK: the image differs from the previous, always on the first); the video
    port under an internal or external trigger (a pairing TI's GUI does not offer: it ties them to
    flash) plays one frame and swaps none. An entry's own buffer_swap, where given, wins."""
    starts = _frame_starts(sequence)
    swaps_frames = sequence.trigger is TriggerMode.VSYNC or sequence.source == "flash"
    return [
        (starts_frame and swaps_frames) if entry.buffer_swap is None else entry.buffer_swap
        for entry, starts_frame in zip(sequence.entries, starts, strict=True)
    ]


def black_after(sequence: PatternSequence, triggers: list[int]) -> list[bool]:
    """Whether each entry inserts black after its exposure.
    - VSYNC: as the entry asks, else none (GUI: "Insert black" unchecked by default for the video
      port; the controller then reports the validator's bit 3, a warning there: see lcr4500).
    - internal or external (SDK, CreateSendStartSequenceLut, written for flash in variable-exposure
      mode 3 and applied here to both LUTs): where exposure differs from period or the entry is not
      internally triggered; not on an entry whose exposure the next one shares (GUI, variable
      exposure: "previous pattern has black-fill pattern inserted" is refused; validator bit 2);
      then on the entry before an externally triggered one (validator bit 3, "post vector was not
      inserted prior to external triggered vector"), and, in a repeating sequence whose first
      entry is externally triggered, on the last (the entry before it; DLPU018 says so of the
      DLPC900, and a single VSYNC entry without black is reported with bit 3 on a DLPC350).
    An entry's own insert_black, where given, wins."""
    entries, times = sequence.entries, timings(sequence)
    if sequence.trigger is TriggerMode.VSYNC:
        return [bool(e.insert_black) for e in entries]
    black = [e != p or t != LUT_TRIGGER_INTERNAL for (e, p), t in zip(times, triggers, strict=True)]
    for k in range(len(black) - 1):
        if entries[k + 1].shares_exposure:
            black[k] = False
    for k in range(len(black)):
        follower = k + 1 if k + 1 < len(black) else (0 if sequence.repeat else None)
        if follower is not None and triggers[follower] == LUT_TRIGGER_EXTERNAL:
            black[k] = True
    return [b if e.insert_black is None else e.insert_black for e, b in zip(entries, black, strict=True)]


def variable_exposure(sequence: PatternSequence) -> bool:
    """Whether any pattern has its own exposure: the variable-exposure LUT (trigger modes 3, 4)."""
    return any(e.exposure_us is not None or e.period_us is not None for e in sequence.entries)


def timings(sequence: PatternSequence) -> list[tuple[int, int]]:
    """Each pattern's (exposure, period) in us: its own, else the sequence's."""
    return [
        (
            sequence.exposure_us if e.exposure_us is None else e.exposure_us,
            sequence.period_us if e.period_us is None else e.period_us,
        )
        for e in sequence.entries
    ]


def variable_exposure_entry(word: bytes, exposure_us: int, period_us: int) -> bytes:
    """One MBOX_EXP_DATA entry (TI DLPC350_SendVarExpPatLut): the LUT word as a uint32, then the
    exposure and the period, uint32 little-endian each: 12 bytes."""
    return word + b"\0" + struct.pack("<II", exposure_us, period_us)


def variable_exposure_config(entries: int, images: int, repeat: bool) -> bytes:
    """EXP_PAT_CONFIG (TI DLPC350_SetVarExpPatternConfig): entries - 1 and patterns per TRIG_OUT_2
    - 1 as uint16, images - 1 and repeat as one byte each: 6 bytes."""
    return struct.pack("<HHBB", entries - 1, entries - 1, max(1, images) - 1, int(repeat))
