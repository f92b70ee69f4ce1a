"""What a preloaded pattern sequence is: its patterns (bit-plane groups, LEDs, triggers, black and
buffer swaps, their own exposure) and how it plays. Projectors in SEQUENCE mode take these
(drivers.base.Projector.load_sequence); cameras take TriggerMode too."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np


class TriggerMode(enum.Enum):
    """What advances a preloaded pattern sequence."""

    INTERNAL = "internal"  # the projector's own clock (exposure and period)
    EXTERNAL = "external"  # a pulse on its trigger input
    VSYNC = "vsync"  # each frame of the video input


class EntryTrigger(enum.Enum):
    """What starts one pattern of a sequence, where it differs from the sequence's TriggerMode."""

    INTERNAL = "internal"  # the projector's own clock
    EXTERNAL = "external"  # a pulse on its trigger input
    CONTINUE = "continue"  # no trigger of its own: it follows the previous pattern's


@dataclass(frozen=True)
class SequenceEntry:
    """One pattern of a preloaded sequence: which bit-plane group of the source, its bit depth,
    which LEDs light it ("r", "g", "b" in any mix), what starts it (None: the sequence's trigger
    mode), whether the projector goes black after it (a gap before the next pattern) or swaps its
    frame buffer first (None for either: as the projector's own software would set it), and, where
    a projector can vary it per pattern, its own exposure and period."""

    pattern: int  # bit-plane group (0-24 on a DLPC350; 1-bit pattern 24 is black)
    bit_depth: int = 8
    invert: bool = False
    leds: str = "rgb"
    insert_black: bool | None = None
    buffer_swap: bool | None = None
    trigger: EntryTrigger | None = None
    shares_exposure: bool = False  # lit within the previous pattern's exposure (no trigger, no TRIG_OUT1 of its own)
    exposure_us: int | None = None  # its own exposure and period (variable exposure) instead of the sequence's
    period_us: int | None = None


@dataclass(frozen=True)
class PatternSequence:
    """A sequence a SEQUENCE projector plays on its own; each pattern is lit for `exposure_us` of
    every `period_us` and (where wired) raises the trigger output for the cameras."""

    entries: tuple[SequenceEntry, ...]
    exposure_us: int
    period_us: int
    trigger: TriggerMode = TriggerMode.INTERNAL
    source: str = "video"  # "video": bit-planes of the video input; "flash": stored images
    repeat: bool = False
    images: tuple[np.ndarray, ...] | None = None  # full images, for projectors that take them
    flash_images: tuple[int, ...] = ()  # source "flash": the stored images the patterns come from, in order
    alternate_pairs: bool = False  # external trigger in pairs: one input toggles within a pair, another advances
