"""TI DLP LightCrafter 4500 (DLPC350) over USB HID: video mode, pattern-sequence mode, status.

Written from TI's published DLPC350 command set (command ids and layouts in
../shared/reference/hardware.md section 2.1). It never enters programming mode and never writes the
flash. "Dark" is the LEDs switched off under manual control (LED_ENABLE bit 3 clear, R/G/B clear):
whatever the input shows, no light. Bit 3 set hands the LEDs to the sequencer, which lights them.
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.base import Projector, ProjectorMode
from drivers.dlp.lut import (
    buffer_swaps,
    image_lut_bytes,
    lut_words,
    timings,
    variable_exposure,
    variable_exposure_config,
    variable_exposure_entry,
)
from drivers.dlp.protocol import DlpcProtocol
from drivers.errors import DeviceError, DeviceProtocolError, DeviceStateError, DeviceTimeoutError
from drivers.options import LIGHTCRAFTER_MIN_8BIT_PERIOD_US, LIGHTCRAFTER_RESOLUTION
from drivers.sequences import PatternSequence, TriggerMode
from drivers.usbhid import HidTransport, PyUsbHidTransport

log = logging.getLogger(__name__)

VENDOR_ID, PRODUCT_ID = 0x0451, 0x6401
RESOLUTION = LIGHTCRAFTER_RESOLUTION
MIN_8BIT_PERIOD_US = LIGHTCRAFTER_MIN_8BIT_PERIOD_US
MIN_DARK_GAP_US = 230  # exposure must equal the period or leave this much dark time

CMD_POWER = 0x0200
CMD_VERSION = 0x0205
CMD_STATUS_HW, CMD_STATUS_SYS, CMD_STATUS_MAIN = 0x1A0A, 0x1A0B, 0x1A0C
CMD_LED_ENABLE = 0x1A07
CMD_LUT_VALID = 0x1A1A
CMD_DISPLAY_MODE = 0x1A1B
CMD_TRIG_OUT1 = 0x1A1D
CMD_PATTERN_SOURCE = 0x1A22
CMD_TRIGGER_MODE = 0x1A23
CMD_START_STOP = 0x1A24
CMD_EXPOSURE_PERIOD = 0x1A29
CMD_PATTERN_CONFIG = 0x1A31
CMD_MBOX_ADDRESS, CMD_MBOX_CONTROL, CMD_MBOX_DATA = 0x1A32, 0x1A33, 0x1A34
CMD_NUM_IMAGES = 0x1A42
CMD_EXP_DATA, CMD_EXP_ADDRESS, CMD_EXP_CONFIG = 0x1A3E, 0x1A3F, 0x1A40  # variable exposure

START, PAUSE, STOP = 2, 1, 0
LED_SEQUENCER, LED_RED, LED_GREEN, LED_BLUE = 0x08, 0x01, 0x02, 0x04  # LED_ENABLE bits (TI SetLedEnables)
VALIDATE_BUSY = 0x80
_STATUS_BITS = (0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40)
# LUT_VALID status bits (TI DLPC350 API, DLPC350_CheckPatLutValidate's comments); bit 7: busy.
VALIDATE_ERRORS = {
    0x01: "exposure or frame period invalid",
    0x02: "pattern number invalid",
    0x04: "TRIG_OUT1 continuous or overlapping black",
    0x08: "post vector (black) not inserted before an externally triggered pattern",
    0x10: "frame period minus exposure under 230 us",
}
TRIGGER_CODES = {TriggerMode.VSYNC: 0, TriggerMode.INTERNAL: 1, TriggerMode.EXTERNAL: 1}
ALTERNATE_PAIRS = 2  # trigger mode 2: TRIG_IN_1 alternates the two patterns of a pair, TRIG_IN_2 advances
VARIABLE_TRIGGER_CODES = {TriggerMode.VSYNC: 4, TriggerMode.INTERNAL: 3, TriggerMode.EXTERNAL: 3}
SOURCE_CODES = {"video": 0, "flash": 3}


@dataclass(frozen=True)
class Status:
    hardware: int
    system: int
    main: int

    @property
    def sequencer_running(self) -> bool:
        return bool(self.main & 0x02)


class Lcr4500Projector(Projector):
    """A LightCrafter 4500 that plays preloaded pattern sequences (SEQUENCE mode).

    `transport_factory` opens the HID transport (by default pyusb on 0451:6401); tests give it a
    fake USB device that speaks the DLPC350 protocol.
    """

    mode = ProjectorMode.SEQUENCE

    def __init__(
        self,
        name: str,
        serial_number: str | None = None,
        timeout_s: float = 2.0,
        transport_factory: Callable[[], HidTransport] | None = None,
        validate_timeout_s: float = 2.0,
    ) -> None:
        super().__init__(name)
        self._factory = transport_factory or (lambda: PyUsbHidTransport(VENDOR_ID, PRODUCT_ID, serial_number))
        self._timeout_s = timeout_s
        self._validate_timeout_s = validate_timeout_s
        self._transport: HidTransport | None = None
        self._protocol: DlpcProtocol | None = None
        self.version: tuple[int, int, int, int] | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        return RESOLUTION

    @property
    def _p(self) -> DlpcProtocol:
        if self._protocol is None:
            raise DeviceStateError(f"{self.name}: device is not open")
        return self._protocol

    # --- lifecycle -------------------------------------------------------------------------
    def _do_open(self) -> None:
        self._transport = self._factory()
        self._protocol = DlpcProtocol(self._transport, self.name, self._timeout_s)
        try:
            self.version = struct.unpack("<4I", self._p.read(CMD_VERSION, 16))
            self._do_dark()
        except Exception:
            self._transport.close()
            self._transport = self._protocol = None
            raise

    def _do_close(self) -> None:
        try:
            self._do_dark()
        except DeviceError:
            pass  # a device that is gone is dark
        finally:
            if self._transport is not None:
                self._transport.close()
            self._transport = self._protocol = None

    # --- light -----------------------------------------------------------------------------
    def _do_dark(self) -> None:
        self._p.write(CMD_LED_ENABLE, bytes([0]))  # manual control (bit 3 clear), every LED off

    def lights_on(self) -> None:
        """Hand the LEDs back to the sequencer, which lights them (the opposite of dark)."""
        self._p.write(CMD_LED_ENABLE, bytes([LED_SEQUENCER]))  # the sequencer drives the LEDs again

    def standby(self) -> None:
        """Dark, then the controller's standby (POWER_CONTROL 1: the DMD parked, the LEDs off);
        a sequence must be loaded again after wake()."""
        self._require_open()
        self._guarded(self._power, True)

    def wake(self) -> None:
        """Out of standby (POWER_CONTROL 0), still dark."""
        self._require_open()
        self._guarded(self._power, False)

    def _power(self, standby: bool) -> None:
        if standby:  # as TI's GUI: stopped, then video mode, then standby
            self._p.write(CMD_START_STOP, bytes([STOP]))
            self._do_dark()
            self.set_display_mode(False)
        self._p.write(CMD_POWER, bytes([int(standby)]))

    def _do_show(self, pattern: np.ndarray) -> None:
        raise DeviceStateError(f"{self.name}: plays preloaded sequences; use load_sequence and start_sequence")

    # --- status and modes ------------------------------------------------------------------
    def status(self) -> Status:
        self._require_open()
        return Status(
            self._p.read(CMD_STATUS_HW, 1)[0], self._p.read(CMD_STATUS_SYS, 1)[0], self._p.read(CMD_STATUS_MAIN, 1)[0]
        )

    def display_mode(self) -> str:
        return "pattern" if self._p.read(CMD_DISPLAY_MODE, 1)[0] else "video"

    def set_display_mode(self, pattern: bool, polls: int = 6, interval_s: float = 0.1) -> None:
        """Switch between video and pattern mode and wait for the controller to report it."""
        self._p.write(CMD_DISPLAY_MODE, bytes([int(pattern)]))
        for _ in range(polls):
            if self._p.read(CMD_DISPLAY_MODE, 1)[0] == int(pattern):
                return
            time.sleep(interval_s)
        raise DeviceTimeoutError(f"{self.name}: display mode did not change within {polls * interval_s:g} s")

    def video_mode(self, lit: bool = True) -> None:
        """Stop any sequence and show the video input (the projector as a plain HDMI display),
        with the LEDs on, or off until lights_on()."""
        self._require_open()
        self._guarded(self._to_video, lit)

    def _to_video(self, lit: bool) -> None:
        self._p.write(CMD_START_STOP, bytes([STOP]))
        self.set_display_mode(False)
        if lit:
            self.lights_on()

    # --- sequences -------------------------------------------------------------------------
    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        if sequence.images is not None:
            raise DeviceStateError(
                f"{self.name}: images reach a LightCrafter through its video input (HDMI) or "
                "its flash; this driver plays bit-planes of what the input shows"
            )
        exposure, period = sequence.exposure_us, sequence.period_us
        for index, (e, t) in enumerate(timings(sequence)):
            if not (e == t or e <= t - MIN_DARK_GAP_US):
                raise ValueError(
                    f"{self.name}: pattern {index}: exposure {e} us must equal the period {t} us or leave "
                    f"{MIN_DARK_GAP_US} us dark"
                )
        if sequence.source not in SOURCE_CODES:
            raise ValueError(f"{self.name}: source must be one of {sorted(SOURCE_CODES)}")
        count = len(sequence.entries)
        if count > 128:
            raise ValueError(f"{self.name}: at most 128 LUT entries, got {count}")
        images = self._flash_images(sequence)
        if sequence.alternate_pairs and (
            sequence.trigger is not TriggerMode.EXTERNAL or count % 2 or variable_exposure(sequence)
        ):
            raise ValueError(
                f"{self.name}: alternating pairs (trigger mode 2) take an external trigger, an even number "
                "of patterns and one exposure for all"
            )
        p = self._p
        p.write(CMD_START_STOP, bytes([STOP]))
        self.set_display_mode(True)
        p.write(CMD_PATTERN_SOURCE, bytes([SOURCE_CODES[sequence.source]]))
        if variable_exposure(sequence):
            self._write_variable_exposure(sequence, images)
            self._validate(sequence.trigger is TriggerMode.VSYNC)
            return
        # images - 1: the flash images, or (video port) the frames, counted as TI's GUI counts them:
        # the LUT's buffer swaps (on_pushButton_PatSeqSendLUT_clicked; the API calls it ignored there)
        frames = len(images) if images else sum(buffer_swaps(sequence))
        p.write(CMD_PATTERN_CONFIG, bytes([count - 1, int(sequence.repeat), count - 1, max(1, frames) - 1]))
        mode = ALTERNATE_PAIRS if sequence.alternate_pairs else TRIGGER_CODES[sequence.trigger]
        p.write(CMD_TRIGGER_MODE, bytes([mode]))
        p.write(CMD_EXPOSURE_PERIOD, struct.pack("<II", exposure, period))
        self._write_mailbox(2, list(enumerate(lut_words(sequence))), CMD_MBOX_ADDRESS, CMD_MBOX_DATA)
        if images:  # the image-index table (TI DLPC350_SendImageLut: all indices in one write)
            self._write_mailbox(1, [(0, image_lut_bytes(images))], CMD_MBOX_ADDRESS, CMD_MBOX_DATA)
        self._validate(sequence.trigger is TriggerMode.VSYNC)

    def _write_variable_exposure(self, sequence: PatternSequence, images: tuple[int, ...]) -> None:
        """Trigger mode 3 (internal or external) or 4 (VSYNC), then the image table, the LUT of
        12-byte entries through mailbox 3, and EXP_PAT_CONFIG, in the order of TI's sample code."""
        p = self._p
        p.write(CMD_TRIGGER_MODE, bytes([VARIABLE_TRIGGER_CODES[sequence.trigger]]))
        if images:
            self._write_mailbox(1, [(0, image_lut_bytes(images))], CMD_EXP_ADDRESS, CMD_MBOX_DATA)
        entries = [
            (index, variable_exposure_entry(word, *timing))
            for index, (word, timing) in enumerate(zip(lut_words(sequence), timings(sequence), strict=True))
        ]
        self._write_mailbox(3, entries, CMD_EXP_ADDRESS, CMD_EXP_DATA)
        frames = len(images) if images else sum(buffer_swaps(sequence))  # as PAT_CONFIG's (TI's GUI)
        p.write(CMD_EXP_CONFIG, variable_exposure_config(len(entries), frames, sequence.repeat))

    def _write_mailbox(self, mailbox: int, items: list[tuple[int, bytes]], address: int, data: int) -> None:
        """Open `mailbox`, write each item at its address (uint16 for the variable-exposure
        address), close it whatever happens."""
        p = self._p
        p.write(CMD_MBOX_CONTROL, bytes([mailbox]))
        try:
            for offset, payload in items:
                p.write(address, offset.to_bytes(2 if address == CMD_EXP_ADDRESS else 1, "little"))
                p.write(data, payload)
        finally:
            p.write(CMD_MBOX_CONTROL, bytes([0]))

    def _flash_images(self, sequence: PatternSequence) -> tuple[int, ...]:
        """A flash sequence's image indices, each one the flash holds; ValueError naming the rule."""
        images = sequence.flash_images
        if sequence.source != "flash":
            if images:
                raise ValueError(f"{self.name}: flash_images are for a sequence whose source is flash")
            return ()
        if not 1 <= len(images) <= 64:
            raise ValueError(f"{self.name}: a flash sequence names 1 to 64 stored images, not {len(images)}")
        stored = self._p.read(CMD_NUM_IMAGES, 1)[0]
        missing = sorted({i for i in images if not 0 <= i < stored})
        if missing:
            raise ValueError(f"{self.name}: the flash holds images 0..{stored - 1}; {missing} are not there")
        return images

    def _validate(self, vsync: bool = False) -> None:
        self._p.write(CMD_LUT_VALID, bytes([0]))  # one data byte, 0x00 (TI CmdList; it was sent with none)
        deadline = time.monotonic() + self._validate_timeout_s
        while True:
            status = self._p.read(CMD_LUT_VALID, 1)[0]
            if not status & VALIDATE_BUSY:
                break
            if time.monotonic() > deadline:
                raise DeviceTimeoutError(
                    f"{self.name}: sequence validation still busy after {self._validate_timeout_s:g} s"
                )
            time.sleep(0.01)
        # TI's SDK refuses any status bit (CreateSendStartSequenceLut); its GUI only bits 0 and 1, and
        # the API calls bits 2-4 warnings. slrig refuses any, as the SDK, but for bit 3 under VSYNC:
        # a video frame's first pattern waits for the frame, and TI's own VSYNC LUTs (the GUI's,
        # whose "Insert black" is off there) leave no black before it.
        tolerated = 0x08 if vsync else 0
        if status & tolerated:
            log.info("%s: validation: %s (expected under VSYNC)", self.name, VALIDATE_ERRORS[0x08])
        problems = [
            VALIDATE_ERRORS.get(bit, f"status bit {bit:#04x}") for bit in _STATUS_BITS if status & bit & ~tolerated
        ]
        if problems:
            raise DeviceProtocolError(f"{self.name}: the controller rejected the sequence: {'; '.join(problems)}")

    def _do_start_sequence(self, group: int = 0) -> None:
        self.lights_on()
        self._p.write(CMD_START_STOP, bytes([START]))

    def _do_stop_sequence(self) -> None:
        self._p.write(CMD_START_STOP, bytes([STOP]))
        self._do_dark()

    def configure_trigger_out(
        self, invert: bool = False, rising_delay_ns: float = 0.0, falling_delay_ns: float = 0.0
    ) -> None:
        """TRIG_OUT_1 around each pattern's exposure; delays in steps of 107.2 ns about 0xBB = 0."""

        def code(delay_ns: float) -> int:
            value = round(0xBB + delay_ns / 107.2)
            if not 0 <= value <= 0xFF:
                raise ValueError(f"trigger delay {delay_ns} ns is outside -20.05..+7.3 us")
            return value

        self._require_open()
        self._p.write(CMD_TRIG_OUT1, bytes([int(invert), code(rising_delay_ns), code(falling_delay_ns)]))
