"""The contract every projector keeps is in drivers.testing (run by tests/test_contracts.py);
here, golden packets and the faults particular to each driver."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.dlp.lcr4500 import PRODUCT_ID, VENDOR_ID, Lcr4500Projector
from drivers.dlp.lut import lut_entry
from drivers.dlp.protocol import encode
from drivers.errors import (
    DeviceDisconnectedError,
    DeviceError,
    DeviceNotFoundError,
    DeviceProtocolError,
    DeviceTimeoutError,
)
from drivers.fakes.dlpc350 import FakeLcr4500, Faults, finder_for
from drivers.hdmi.projector import HdmiProjector
from drivers.sequences import PatternSequence, SequenceEntry, TriggerMode
from drivers.usbhid import PyUsbHidTransport

SEQUENCE = PatternSequence(tuple(SequenceEntry(i % 3, 8) for i in range(6)), 8333, 8333, TriggerMode.EXTERNAL)


def test_dark_and_lit_are_tis_led_enable_bytes() -> None:
    """TI DLPC350_SetLedEnables: bit 3 = sequencer control (it lights the LEDs), bits 0-2 = R, G, B
    under manual control. Dark is manual with all off: 0x00; playing a sequence hands over: 0x08."""
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    led_writes = [data for kind, command, data in fake.log if kind == "w" and command == 0x1A07]
    assert led_writes[-1] == bytes([0x00]) and fake.dark
    projector.load_sequence(SEQUENCE)
    projector.start_sequence()
    led_writes = [data for kind, command, data in fake.log if kind == "w" and command == 0x1A07]
    assert led_writes[-1] == bytes([0x08]) and not fake.dark


def _lcr(device: FakeLcr4500 | None, timeout_s: float = 0.5) -> Lcr4500Projector:
    return Lcr4500Projector(
        "lcr",
        timeout_s=timeout_s,
        validate_timeout_s=0.3,
        transport_factory=lambda: PyUsbHidTransport(VENDOR_ID, PRODUCT_ID, finder=finder_for(device)),
    )


# --- the LightCrafter 4500 driver on its protocol fake ---------------------------------------
def test_golden_packets() -> None:
    assert encode(0x1A1B, b"\x01", 0x2A, read=False, reply=True)[:7] == bytes(
        [0x40, 0x2A, 0x03, 0x00, 0x1B, 0x1A, 0x01]
    )
    assert encode(0x1A1B, b"\x01", 0x2A, read=False, reply=True)[7:] == bytes(57)
    assert encode(0x1A0C, b"", 7, read=True, reply=True)[:6] == bytes([0xC0, 0x07, 0x02, 0x00, 0x0C, 0x1A])
    # LUT word: external positive trigger, pattern 2, 8 bits, white, no invert
    assert lut_entry(2, 8, 1) == (1 | (2 << 2) | (8 << 8) | (0b111 << 12)).to_bytes(3, "little")
    with pytest.raises(ValueError):
        lut_entry(3, 8, 0)  # a 24-bit frame holds three 8-bit patterns: 0, 1, 2
    assert lut_entry(23, 1, 0)[0] == 23 << 2  # and 24 one-bit planes


def test_sequence_reaches_the_controller() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    assert not fake.kernel_driver_active and fake.claimed  # usbhid detached, interface claimed
    projector.configure_trigger_out(rising_delay_ns=0.0)
    projector.load_sequence(SEQUENCE)
    assert fake.display_mode == 1 and fake.source == 0 and fake.trigger_mode == 1
    assert (fake.exposure_us, fake.period_us) == (8333, 8333)
    assert [(w >> 2) & 0x3F for w in fake.lut_entries] == [0, 1, 2, 0, 1, 2]
    assert all(w & 0x3 == 1 for w in fake.lut_entries)  # external trigger
    assert fake.trig_out1 == bytes([0, 0xBB, 0xBB])
    projector.start_sequence()
    assert fake.running and projector.status().sequencer_running
    projector.video_mode()
    assert fake.display_mode == 0 and not fake.running
    projector.close()
    assert fake.kernel_driver_active and not fake.claimed  # handed back to usbhid


def test_not_attached() -> None:
    with pytest.raises(DeviceNotFoundError, match="not attached"):
        _lcr(None).open()


def test_busy_at_open() -> None:
    with pytest.raises(DeviceError, match="busy"):
        _lcr(FakeLcr4500(Faults(busy_at_open=True))).open()


def _assert_within(start: float, limit_s: float) -> None:
    assert time.monotonic() - start < limit_s + 0.5


def test_read_timeout_fails_within_its_timeout_and_goes_dark() -> None:
    fake = FakeLcr4500()
    projector = _lcr(fake)
    projector.open()
    projector.load_sequence(SEQUENCE)
    projector.start_sequence()
    assert not fake.dark
    fake.faults.silent_after = fake.commands  # from here on the device's replies are lost
    start = time.monotonic()
    with pytest.raises(DeviceTimeoutError):
        projector.load_sequence(SEQUENCE)
    _assert_within(start, 1.0)  # the failed command's timeout, then the dark command's
    assert fake.dark  # the driver's own dark command reached the device, though its reply was lost


def test_error_bit_is_a_protocol_error_and_the_projector_goes_dark() -> None:
    fake = FakeLcr4500(Faults(error_commands={0x1A29}))
    projector = _lcr(fake)
    projector.open()
    with pytest.raises(DeviceProtocolError, match="0x1a29 failed"):
        projector.load_sequence(SEQUENCE)
    assert fake.dark


def test_unplug_mid_sequence() -> None:
    fake = FakeLcr4500(Faults(unplug_after=12))
    projector = _lcr(fake)
    projector.open()
    with pytest.raises(DeviceDisconnectedError):
        projector.load_sequence(SEQUENCE)
    projector.close()  # closing a device that is gone does not raise
    assert not projector.is_open


def test_a_late_reply_is_not_taken_for_the_next_answer() -> None:
    fake = FakeLcr4500(Faults(late_reply_before=3))
    projector = _lcr(fake)
    projector.open()
    assert projector.display_mode() == "video"  # command 3: a stale reply (payload 0x00) comes first
    fake.display_mode = 1
    assert projector.display_mode() == "pattern"


def test_validation_that_never_finishes_times_out() -> None:
    fake = FakeLcr4500(Faults(validate_busy_forever=True))
    projector = _lcr(fake)
    projector.open()
    start = time.monotonic()
    with pytest.raises(DeviceTimeoutError, match="validation"):
        projector.load_sequence(SEQUENCE)
    _assert_within(start, 0.3)
    assert fake.dark


def test_the_controller_rejects_a_bad_exposure_and_the_driver_says_why() -> None:
    projector = _lcr(FakeLcr4500())
    projector.open()
    with pytest.raises(ValueError, match="230 us"):
        projector.load_sequence(PatternSequence(SEQUENCE.entries, 8200, 8333))


def test_mode_read_back_lag_is_waited_for() -> None:
    fake = FakeLcr4500(Faults(mode_lag_reads=3))
    projector = _lcr(fake)
    projector.open()
    projector.load_sequence(SEQUENCE)
    assert fake.display_mode == 1


# --- the HDMI display worker -------------------------------------------------------------------
def test_hdmi_worker_reports_each_presentation() -> None:
    with HdmiProjector("hdmi", (64, 48), video_driver="offscreen") as projector:
        times = []
        for value in (40, 120, 250):
            projector.show(np.full((48, 64), value, np.uint8))  # the driver checks the displayed checksum
            times.append(projector.last_present_s)
        assert times == sorted(times) and len(set(times)) == 3


def test_hdmi_worker_killed_mid_scan_is_a_disconnect() -> None:
    import os
    import signal

    # the answer's bound gives a loaded machine time to finish the killed worker: with 1 s, two
    # busy cores once left it alive past the wait, a timeout instead of a disconnect
    projector = HdmiProjector("hdmi", (64, 48), video_driver="offscreen", timeout_s=5.0)
    with projector:
        projector.show(np.full((48, 64), 200, np.uint8))
        assert projector.worker_pid is not None
        os.kill(projector.worker_pid, signal.SIGKILL)
        start = time.monotonic()
        killed = projector.worker_pid
        with pytest.raises(DeviceDisconnectedError):
            for _ in range(3):  # the pipe may take a write to notice
                projector.show(np.full((48, 64), 10, np.uint8))
        assert time.monotonic() - start < 15.0  # three shows' bounds: noticed, not waited out
        # the fault left the output to a new worker holding it black
        assert projector.worker_pid not in (None, killed) and projector.is_dark
        projector.show(np.full((48, 64), 77, np.uint8))  # and the projector works again
    assert projector.worker_pid is None


def test_hdmi_without_a_display_says_so() -> None:
    with pytest.raises(DeviceNotFoundError, match="no display"):
        HdmiProjector("hdmi", (64, 48), video_driver="no-such-driver", start_timeout_s=5.0).open()
