"""The DLPC350 pattern LUT: entries packed as TI's DLPC350_AddToPatLut packs them (DLPC350
Programmer's Guide table 2-65), the words of a whole sequence, and the image-index table."""

from __future__ import annotations

import struct

from drivers.base import PatternSequence, SequenceEntry, TriggerMode

LUT_TRIGGER_INTERNAL, LUT_TRIGGER_EXTERNAL, LUT_TRIGGER_CONTINUE = 0, 1, 3  # LUT bits 1:0 (0 is VSYNC in VSYNC mode)


LED_BITS = {"r": 0b001, "g": 0b010, "b": 0b100}  # LUT bits 14:12 (TI DLPC350_AddToPatLut)


def lut_entry(
    pattern: int,
    bit_depth: int,
    trigger: int,
    invert: bool = False,
    led: int = 0b111,
    buffer_swap: bool = False,
    insert_black: bool = False,
) -> bytes:
    """The 24-bit pattern LUT word (little-endian): trigger 1:0, pattern 7:2, bit depth 11:8,
    LEDs 14:12, invert 16, insert black 17, buffer swap 18. A 24-bit frame holds 24 // bit_depth
    patterns (8-bit: 0 green, 1 red, 2 blue; 1-bit: planes 0..23); ValueError names the rule broken."""
    if not 1 <= bit_depth <= 8:
        raise ValueError(f"bit depth {bit_depth} is outside 1..8 (LUT bits 11:8)")
    if not 0 <= pattern < 24 // bit_depth:
        raise ValueError(
            f"pattern number {pattern} is outside 0..{24 // bit_depth - 1}: a 24-bit frame holds "
            f"{24 // bit_depth} patterns of {bit_depth} bits"
        )
    if not 0 <= led <= 0b111:
        raise ValueError(f"LED selection {led:#b} is not a mix of red, green and blue (LUT bits 14:12)")
    word = trigger | (pattern << 2) | (bit_depth << 8) | (led << 12) | (int(invert) << 16)
    word |= (int(insert_black) << 17) | (int(buffer_swap) << 18)
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
    """LUT words of a sequence. Under VSYNC each video frame's first pattern waits for the frame
    and swaps to its buffer; the frame's other patterns follow it without a trigger. From flash,
    each image's first pattern swaps to the next image of the image LUT. A pattern number not
    above the previous one's starts the next frame or image (8-bit: green, red, blue)."""
    words, previous = [], -1
    for entry in sequence.entries:
        starts_frame = entry.pattern <= previous or not words  # of a video frame, or of a flash image
        previous = entry.pattern
        if sequence.trigger is TriggerMode.VSYNC:
            trigger = LUT_TRIGGER_INTERNAL if starts_frame else LUT_TRIGGER_CONTINUE
            swap = starts_frame
        else:
            trigger = LUT_TRIGGER_EXTERNAL if sequence.trigger is TriggerMode.EXTERNAL else LUT_TRIGGER_INTERNAL
            swap = starts_frame and sequence.source == "flash"  # the next image of the image LUT
        swap = swap if entry.buffer_swap is None else entry.buffer_swap
        led, black = leds_of(entry), entry.insert_black
        words.append(lut_entry(entry.pattern, entry.bit_depth, trigger, entry.invert, led, swap, black))
    return words


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
