"""A protocol fake of the LightCrafter 4500: a pyusb-style USB device that speaks DLPC350 HID
reports, keeps the controller's registers, validates sequences, and injects faults. The real
driver (drivers.dlp.lcr4500 over drivers.usbhid) runs against it unchanged."""

from __future__ import annotations

import errno
import struct
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from drivers.dlp import lcr4500 as lcr
from drivers.dlp.commands import COMMANDS, IMAGE_LUT, PATTERN_LUT_ENTRY
from drivers.dlp.lut import LUT_TRIGGER_CONTINUE, MIN_EXPOSURE_US, patterns_of_depth
from drivers.faults import Fault, FaultPlan


def _refusal(command: int, data: bytes, read: bool, mailbox: int) -> str | None:
    """Why the DLPC350 command list refuses this report (drivers.dlp.commands), or None; mailbox
    data is judged by the mailbox open (a pattern LUT entry, or the image indices)."""
    known = COMMANDS.get(command)
    if known is None:
        return f"unknown command 0x{command:04x}"
    if read:
        return None if known.read_bytes is not None else f"{known.name} is not read"
    if command == lcr.CMD_MBOX_DATA:
        known = {1: IMAGE_LUT, 2: PATTERN_LUT_ENTRY}.get(mailbox, known)
    return known.refuses(data)


def _usb_error(code: int, text: str) -> Exception:
    import usb.core

    return usb.core.USBError(text, -1, code)


@dataclass
class Faults:
    busy_at_open: bool = False  # claiming the interface fails with EBUSY (usbhid or another program has it)
    silent_after: int | None = None  # after this many commands replies are lost (read timeout); writes still act
    unplug_after: int | None = None  # after this many commands the device is gone (ENODEV)
    error_commands: set[int] = field(default_factory=set)  # these commands reply with the error bit
    late_reply_before: int | None = None  # before answering this command, first send a stale reply
    validate_busy_forever: bool = False
    mode_lag_reads: int = 0  # the display-mode read-back lags this many reads behind a write


class _Context:
    """The part of pyusb's device context that usb.util's claim/release/dispose calls."""

    def __init__(self, device: FakeLcr4500) -> None:
        self._device = device

    def managed_claim_interface(self, device: Any, interface: int) -> None:
        self._device._check_plugged()
        if self._device.faults.busy_at_open:
            raise _usb_error(errno.EBUSY, "Resource busy")
        self._device.claimed = True

    def managed_release_interface(self, device: Any, interface: int) -> None:
        self._device.claimed = False

    def dispose(self, device: Any) -> None:
        self._device.disposed = True


class FakeLcr4500:
    """The USB device: `write`/`read` on endpoints 0x01/0x81, 64-byte reports.

    `video_period_us` is the frame period of what arrives on the video input; `on_start` is called
    whenever a sequence starts, so a test can put its light on a simulated scene.
    """

    def __init__(
        self, faults: Faults | None = None, video_period_us: int = 16667, plan: FaultPlan | None = None
    ) -> None:
        self.faults = faults or Faults()
        if plan is not None:  # counted in commands
            if plan.fault is Fault.SILENCE:
                self.faults.silent_after = plan.after
            else:
                self.faults.unplug_after = plan.after
        self.video_period_us = video_period_us
        self.on_start: Callable[[FakeLcr4500], None] | None = None
        self.starts = 0
        self._ctx = _Context(self)
        self.kernel_driver_active = True
        self.claimed = False
        self.disposed = False
        self.plugged = True
        self.commands = 0
        self.log: list[tuple[str, int, bytes]] = []  # ("w"/"r", command, data)
        self.reports: list[bytes] = []  # every report as written
        self.refused: list[str] = []  # why each refused report was refused
        self._replies: deque[bytes] = deque()
        self._pending_stale: bytes | None = None
        # controller registers
        self.display_mode = 0
        self._reported_mode = 0
        self._mode_lag = 0
        self.led_enable = 0
        self.source = 0
        self.trigger_mode = 1
        self.exposure_us, self.period_us = 0, 0
        self.pattern_config = bytes(4)
        self.mailbox = 0
        self.mailbox_address = 0
        self.lut: dict[int, bytes] = {}
        self.running = False
        self.validated = False
        self._validate_reads = 0
        self.trig_out1 = bytes(3)
        self.standby = False
        self.images_in_flash = 8  # what the flash holds (the LightCrafter's factory images are fewer)
        self.image_lut: list[int] = []
        self.exp_lut: dict[int, bytes] = {}  # the variable-exposure LUT: 12-byte entries
        self.exp_config = bytes(6)

    # --- what pyusb and usb.util call ---------------------------------------------------
    def is_kernel_driver_active(self, interface: int) -> bool:
        self._check_plugged()
        return self.kernel_driver_active

    def detach_kernel_driver(self, interface: int) -> None:
        self.kernel_driver_active = False

    def attach_kernel_driver(self, interface: int) -> None:
        self.kernel_driver_active = True

    def set_configuration(self) -> None:
        self._check_plugged()

    def write(self, endpoint: int, data: bytes, timeout: int) -> int:
        self._check_plugged()
        if endpoint != 0x01 or len(data) != 64:
            raise _usb_error(errno.EINVAL, "bad write")
        self.reports.append(bytes(data))
        self._handle(bytes(data))
        return len(data)

    def read(self, endpoint: int, size: int, timeout: int) -> bytes:
        self._check_plugged()
        if not self._replies:
            raise _usb_error(errno.ETIMEDOUT, "Operation timed out")
        return self._replies.popleft()

    # --- the controller ------------------------------------------------------------------
    @property
    def dark(self) -> bool:
        """No light: LEDs under manual control (bit 3 clear, as TI's SetLedEnables documents) with
        none of red, green, blue enabled. Bit 3 set gives them to the sequencer, which lights them."""
        return self.standby or (not self.led_enable & lcr.LED_SEQUENCER and not self.led_enable & 0x07)

    @property
    def lut_entries(self) -> list[int]:
        if self.variable:
            count = int.from_bytes(self.exp_config[:2], "little") + 1
            return [int.from_bytes(self.exp_lut.get(i, bytes(12))[:3], "little") for i in range(count)]
        count = self.pattern_config[0] + 1
        return [int.from_bytes(self.lut.get(i, bytes(3)), "little") for i in range(count)]

    @property
    def variable(self) -> bool:
        """Trigger mode 3 or 4: the variable-exposure LUT, each entry with its exposure and period."""
        return self.trigger_mode in (3, 4)

    def timings(self) -> list[tuple[int, int]]:
        """Each LUT entry's (exposure, period) in us."""
        if not self.variable:
            return [(self.exposure_us, self.period_us)] * len(self.lut_entries)
        entries = [self.exp_lut.get(i, bytes(12)) for i in range(len(self.lut_entries))]
        return [struct.unpack_from("<II", entry, 4) for entry in entries]

    def _check_plugged(self) -> None:
        if not self.plugged:
            raise _usb_error(errno.ENODEV, "No such device (it may have been disconnected)")

    def _handle(self, report: bytes) -> None:
        flags, sequence, length, command = struct.unpack_from("<BBHH", report)
        data = report[6 : 4 + length]
        self.commands += 1
        f = self.faults
        if f.unplug_after is not None and self.commands > f.unplug_after:
            self.plugged = False
            raise _usb_error(errno.ENODEV, "No such device (it may have been disconnected)")
        silent = f.silent_after is not None and self.commands > f.silent_after
        read = bool(flags & 0x80)
        self.log.append(("r" if read else "w", command, data))
        if f.late_reply_before is not None and self.commands == f.late_reply_before:
            self._replies.append(self._reply((sequence - 1) & 0xFF, b"\x00"))  # the previous command's, late
        refused = _refusal(command, data, read, self.mailbox)
        if refused is not None:
            self.refused.append(refused)
            payload, error = b"", True  # what the command list refuses: the error bit, nothing changed
        else:
            try:
                payload = self._read(command) if read else self._write(command, data)
                error = command in f.error_commands
            except KeyError:
                payload, error = b"", True  # a command the controller cannot do now: the error bit
        if flags & 0x40 and not silent:
            self._replies.append(self._reply(sequence, payload, error))

    def _reply(self, sequence: int, payload: bytes, error: bool = False) -> bytes:
        flags = 0x20 if error else 0
        return struct.pack("<BBH", flags, sequence, len(payload)).__add__(payload).ljust(64, b"\0")

    def _read(self, command: int) -> bytes:
        if command == lcr.CMD_VERSION:
            return struct.pack("<4I", 0x0303_0000, 0x0001_0000, 0, 0)
        if command == lcr.CMD_STATUS_MAIN:
            return bytes([0x01 | (0x02 if self.running else 0)])
        if command in (lcr.CMD_STATUS_HW, lcr.CMD_STATUS_SYS):
            return bytes([0x01])
        if command == lcr.CMD_DISPLAY_MODE:
            if self._mode_lag > 0:
                self._mode_lag -= 1
            else:
                self._reported_mode = self.display_mode
            return bytes([self._reported_mode])
        if command == lcr.CMD_LUT_VALID:
            self._validate_reads += 1
            if self.faults.validate_busy_forever or self._validate_reads < 3:
                return bytes([lcr.VALIDATE_BUSY])
            return bytes([self._validation_errors()])
        if command == lcr.CMD_START_STOP:
            return bytes([lcr.START if self.running else lcr.STOP])
        if command == lcr.CMD_LED_ENABLE:
            return bytes([self.led_enable])
        if command == lcr.CMD_NUM_IMAGES:
            return bytes([self.images_in_flash])
        raise KeyError(command)

    def _validation_errors(self) -> int:
        """The LUT_VALID status as the controller reports it (TI DLPC350 API's bit meanings): 0x01
        exposure or period (exposure above the period, below its bit depth's minimum), 0x02 a
        pattern number (TI GUI's ranges per depth), 0x04 black inside an exposure the next pattern
        shares (trigger-out-previous), 0x08 no black before an externally triggered pattern (the
        last entry counting as the one before the first where the LUT plays round: repeating, or
        under VSYNC,
        where a frame's first entry is triggered: a DLPC350 reports it for a single VSYNC entry
        without black) or, outside VSYNC, after one shorter than its period, 0x10 dark time under
        230 us."""
        bits = 0
        vsync = self.trigger_mode in (0, 4) and self.source == 0
        words, times = self.lut_entries, self.timings()
        repeat = bool(self.exp_config[5] if self.variable else self.pattern_config[1])
        plays_round = repeat or vsync  # video frames keep coming
        for k, (word, (e, p)) in enumerate(zip(words, times, strict=True)):
            depth = max(1, (word >> 8) & 0xF)
            black = bool(word & (1 << 17))
            if e <= 0 or p <= 0 or e > p or e < MIN_EXPOSURE_US[min(depth, 8) - 1]:
                bits |= 0x01
            elif e != p and p - e < lcr.MIN_DARK_GAP_US:
                bits |= 0x10
            if ((word >> 2) & 0x3F) >= patterns_of_depth(min(depth, 8)):  # e.g. an 8-bit pattern other than 0, 1, 2
                bits |= 0x02
            following = words[(k + 1) % len(words)] if k + 1 < len(words) or plays_round else None
            shared_next = k + 1 < len(words) and bool(words[k + 1] & (1 << 19))
            if not black and following is not None and following & 0x3 in (1, 2):
                bits |= 0x08
            if not vsync and not black and not shared_next and e < p:
                bits |= 0x08
            if black and shared_next:  # black inside an exposure two patterns share
                bits |= 0x04
        images = self.exp_config[4] if self.variable else self.pattern_config[3]
        if self.source == 3 and (not self.image_lut or len(self.image_lut) != images + 1):
            bits |= 0x02  # a flash sequence's images: the table and the count in the configuration agree
        p = self.period_us
        if vsync:  # a video frame's patterns fit in its period
            frames = self.vsync_frames()
            if any(len(frame) * p > self.video_period_us for frame in frames):
                bits |= 0x01
        return bits

    def displayed_patterns(self, frame: Any) -> list[Any]:
        """What the DMD shows for each LUT entry of a video-port sequence, from the RGB input
        frame (H x W x 3): an 8-bit pattern's bit-plane group 0 is G7-G0, 1 is R7-R0, 2 is B7-B0."""
        channel = {0: 1, 1: 0, 2: 2}
        return [frame[:, :, channel[(word >> 2) & 0x3F]] for word in self.lut_entries]

    def vsync_frames(self) -> list[list[int]]:
        """The LUT split into video frames: each starts at an entry that waits for VSYNC."""
        frames: list[list[int]] = []
        for word in self.lut_entries:
            if word & 0x3 != LUT_TRIGGER_CONTINUE or not frames:
                frames.append([])
            frames[-1].append(word)
        return frames

    def _write(self, command: int, data: bytes) -> bytes:
        if command == lcr.CMD_DISPLAY_MODE:
            self.display_mode = data[0]
            self._mode_lag = self.faults.mode_lag_reads
            self.running = False
        elif command == lcr.CMD_LED_ENABLE:
            self.led_enable = data[0]
        elif command == lcr.CMD_PATTERN_SOURCE:
            self.source = data[0]
        elif command == lcr.CMD_TRIGGER_MODE:
            self.trigger_mode = data[0]
        elif command == lcr.CMD_EXPOSURE_PERIOD:
            self.exposure_us, self.period_us = struct.unpack("<II", data[:8])
        elif command == lcr.CMD_PATTERN_CONFIG:
            self.pattern_config = bytes(data[:4])
        elif command == lcr.CMD_MBOX_CONTROL:
            self.mailbox = data[0]
        elif command in (lcr.CMD_MBOX_ADDRESS, lcr.CMD_EXP_ADDRESS):
            self.mailbox_address = int.from_bytes(data, "little")
        elif command == lcr.CMD_EXP_DATA:
            if self.mailbox != 3:
                raise KeyError(command)  # the variable-exposure LUT's mailbox is not open
            self.exp_lut[self.mailbox_address] = bytes(data)
        elif command == lcr.CMD_EXP_CONFIG:
            self.exp_config = bytes(data)
        elif command == lcr.CMD_MBOX_DATA:
            if self.mailbox == 1:  # the firmware reads a two-entry table backwards (TI DLPC350_SendImageLut)
                self.image_lut = list(data[::-1] if len(data) == 2 else data)
            elif self.mailbox == 2:
                self.lut[self.mailbox_address] = bytes(data[:3])
            else:
                raise KeyError(command)  # mailbox data with the mailbox closed fails
        elif command == lcr.CMD_LUT_VALID:
            self._validate_reads = 0
            self.validated = True
        elif command == lcr.CMD_START_STOP:
            if data[0] == lcr.START and (not self.validated or self.display_mode != 1 or self.standby):
                raise KeyError(command)  # starting an unvalidated sequence fails
            self.running = data[0] == lcr.START
            if self.running:
                self.starts += 1
                if self.on_start is not None:
                    self.on_start(self)
        elif command == lcr.CMD_TRIG_OUT1:
            self.trig_out1 = bytes(data[:3])
        elif command == lcr.CMD_POWER:
            self.standby = data[0] == 1
            self.running = self.running and not self.standby
            self.validated = self.validated and not self.standby  # the LUT is loaded again after waking
        else:
            raise KeyError(command)
        return b""


def finder_for(device: FakeLcr4500 | None):  # type: ignore[no-untyped-def]
    """A stand-in for usb.core.find that finds `device` (None: nothing attached)."""

    def find(**kwargs: Any) -> FakeLcr4500 | None:
        if device is None or not device.plugged:
            return None
        if kwargs.get("idVendor") != lcr.VENDOR_ID or kwargs.get("idProduct") != lcr.PRODUCT_ID:
            return None
        return device

    return find
