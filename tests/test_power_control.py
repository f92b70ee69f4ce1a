"""The contract every power control keeps is in drivers.testing (run by
tests/test_contracts.py); here, each protocol's own faults."""

from __future__ import annotations

import time

import pytest

from drivers.errors import (
    DeviceAuthenticationError,
    DeviceDisconnectedError,
    DeviceError,
    DeviceNotFoundError,
    DeviceProtocolError,
    DeviceTimeoutError,
)
from drivers.fakes.pjlink import FakePJLinkProjector
from drivers.pjlink import PJLinkPowerControl
from drivers.serial_projector import SerialPowerControl

TIMEOUT_S = 0.3


def _serial(vendor: str, fault: str, power: str = "on") -> SerialPowerControl:
    device = SerialPowerControl(
        vendor, f"simprojector://{vendor}?fault={fault}&power={power}", vendor, timeout_s=TIMEOUT_S
    )
    device.open()
    return device


@pytest.mark.parametrize("vendor", ["benq", "epson", "optoma"])
def test_serial_silence_times_out_within_the_timeout(vendor: str) -> None:
    device = _serial(vendor, "silence")
    start = time.monotonic()
    with pytest.raises(DeviceTimeoutError):
        device.power_state()
    assert time.monotonic() - start < TIMEOUT_S + 0.3


@pytest.mark.parametrize("vendor", ["benq", "epson", "optoma"])
def test_serial_garbage_is_a_protocol_error(vendor: str) -> None:
    with pytest.raises(DeviceProtocolError, match="garbled"):
        _serial(vendor, "garbage").power_state()


@pytest.mark.parametrize("vendor", ["benq", "epson", "optoma"])
def test_a_late_reply_is_not_taken_for_the_next_commands_answer(vendor: str) -> None:
    device = _serial(vendor, "late", power="on")
    with pytest.raises(DeviceTimeoutError):
        device.power_state()  # its reply ("on") comes late, when the next command is sent ...
    device._port.fault = ""  # ... and from then on replies are on time
    device.power(False)  # ... so power(False) must not take the late "on" for its own answer
    own = {"benq": "*POW=OFF#", "epson": ":", "optoma": "P"}[vendor]
    assert device.last_reply.strip().endswith(own) and "ON" not in device.last_reply.upper().replace("POW=OFF", "")
    assert device.power_state() == "off"


@pytest.mark.parametrize("vendor", ["benq", "epson", "optoma"])
def test_serial_unplug_and_refusals(vendor: str) -> None:
    with pytest.raises(DeviceDisconnectedError):
        _serial(vendor, "unplug").power(True)
    with pytest.raises(DeviceProtocolError, match=r"refused|Illegal"):
        _serial(vendor, "refuse").power(True)
    with pytest.raises(DeviceTimeoutError, match="incomplete"):
        _serial(vendor, "partial").power_state()


def test_benq_refuses_blank_while_off() -> None:
    with pytest.raises(DeviceProtocolError, match="Block item"):
        _serial("benq", "", power="off").blank(True)


def test_missing_port_and_unknown_vendor() -> None:
    with pytest.raises(DeviceNotFoundError):
        SerialPowerControl("p", "/dev/does-not-exist", "epson").open()
    with pytest.raises(ValueError, match="known: benq, epson, optoma"):
        SerialPowerControl("p", "loop://", "sony")


# --- PJLink faults -------------------------------------------------------------------------------
def test_pjlink_wrong_or_missing_password() -> None:
    with (
        FakePJLinkProjector(password="bench") as server,
        PJLinkPowerControl("pj", "127.0.0.1", server.port, password="guess", timeout_s=TIMEOUT_S) as device,
        pytest.raises(DeviceAuthenticationError, match="refused"),
    ):
        device.power_state()
    with (
        FakePJLinkProjector(password="bench") as server,
        pytest.raises(DeviceAuthenticationError, match="asks for a PJLink password"),
    ):
        PJLinkPowerControl("pj", "127.0.0.1", server.port, timeout_s=TIMEOUT_S).open()


def test_pjlink_warm_up_is_err3() -> None:
    with (
        FakePJLinkProjector(warmup_s=5.0) as server,
        PJLinkPowerControl("pj", "127.0.0.1", server.port, timeout_s=TIMEOUT_S) as device,
    ):
        device.power(True)
        assert device.power_state() == "warming"
        with pytest.raises(DeviceError, match="ERR3"):
            device.select_input("31")


@pytest.mark.parametrize(
    ("fault", "error"),
    [("no-greeting", DeviceTimeoutError), ("silence", DeviceTimeoutError), ("drop", DeviceDisconnectedError)],
)
def test_pjlink_silence_and_dropped_connections(fault: str, error: type[Exception]) -> None:
    with FakePJLinkProjector(fault=fault) as server:
        device = PJLinkPowerControl("pj", "127.0.0.1", server.port, timeout_s=TIMEOUT_S)
        start = time.monotonic()
        try:
            with pytest.raises(error):
                device.open()
                device.power_state()
        finally:
            device.close()
        assert time.monotonic() - start < TIMEOUT_S + 0.5


def test_pjlink_nobody_listening() -> None:
    server = FakePJLinkProjector()
    port = server.port
    server.close()
    with pytest.raises(DeviceNotFoundError):
        PJLinkPowerControl("pj", "127.0.0.1", port, timeout_s=TIMEOUT_S).open()


def test_pjlink_reconnects_after_a_timeout_instead_of_reading_a_late_reply() -> None:
    with (
        FakePJLinkProjector(fault="late-once") as server,
        PJLinkPowerControl("pj", "127.0.0.1", server.port, timeout_s=TIMEOUT_S) as device,
    ):
        with pytest.raises(DeviceTimeoutError):
            device.power(True)  # its "OK" comes after the timeout, on a connection now closed
        assert device.power_state() == "on"  # a new connection, the real answer
