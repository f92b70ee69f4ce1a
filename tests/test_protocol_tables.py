"""Drivers checked against the command tables written from the documents: PJLink class 1
(drivers.pjlink_commands) and the serial projectors (drivers.serial_commands). Every line the
driver sends is encoded again here from the table, and the fakes refuse what the table refuses."""

from __future__ import annotations

import re
import socket
import time

import cv2
import pytest
import serial

from drivers.errors import DeviceError
from drivers.fakes.pjlink import FakePJLinkProjector
from drivers.fakes.v4l2 import FakeVideoCapture, V4l2Faults
from drivers.pjlink import PJLinkPowerControl
from drivers.pjlink_commands import COMMANDS
from drivers.serial_commands import SERIAL_COMMANDS
from drivers.serial_projector import COMMAND_SETS, SIM_HANDLERS
from drivers.v4l2 import V4l2Camera
from drivers.v4l2_controls import CONTROLS


def _line(body: str, parameter: str) -> str:
    """`%1` + body + space + parameter (the class 1 syntax), as the table's entry allows it."""
    command = COMMANDS[body]
    assert parameter == "?" or (command.sets is not None and re.fullmatch(command.sets, parameter)), (body, parameter)
    return f"%1{body} {parameter}"


def test_every_pjlink_line_the_driver_sends_is_the_tables() -> None:
    with (
        FakePJLinkProjector() as server,
        PJLinkPowerControl("pj", "127.0.0.1", server.port, timeout_s=2.0) as device,
    ):
        device.power(True)
        assert device.power_state() == "on"
        device.select_input("31")
        device.blank(True)
        device.blank(False)
        assert device.error_status()["lamp"] == "ok"
        device.power(False)
        sent = list(server.received)
    expected = [
        _line("POWR", "1"),
        _line("POWR", "?"),
        _line("INPT", "31"),
        _line("AVMT", "31"),
        _line("AVMT", "30"),
        _line("ERST", "?"),
        _line("POWR", "0"),
    ]
    assert sent == expected
    assert all(re.fullmatch(r"%1[A-Z0-9]{4} \S+", line) for line in sent) and not server.refused


@pytest.mark.parametrize(
    ("line", "answer"),
    [
        ("%1POWR 2", "%1POWR=ERR2"),  # power is 0 or 1
        ("%1INPT 71", "%1INPT=ERR2"),  # input types are 1-5
        ("%1AVMT 41", "%1AVMT=ERR2"),  # mute 10/11, 20/21, 30/31
        ("%1ERST 1", "%1ERST=ERR2"),  # error status is only queried
        ("%1XXXX ?", "%1XXXX=ERR1"),  # not a class 1 command
        ("%1CLSS ?", "%1CLSS=1"),  # a query the table has is answered in its shape
    ],
)
def test_the_pjlink_fake_answers_by_the_table(line: str, answer: str) -> None:
    with FakePJLinkProjector() as server, socket.create_connection(("127.0.0.1", server.port), timeout=2) as s:
        assert s.recv(64) == b"PJLINK 0\r"
        s.sendall(line.encode() + b"\r")
        reply = s.recv(64).decode()
    assert reply == answer + "\r"
    body = line[2:6]
    if body in COMMANDS and not answer.endswith(("ERR1", "ERR2")):
        assert re.fullmatch(COMMANDS[body].answer, reply[7:-1])


def test_an_input_the_table_refuses_never_leaves_the_driver() -> None:
    with (
        FakePJLinkProjector() as server,
        PJLinkPowerControl("pj", "127.0.0.1", server.port, timeout_s=2.0) as device,
    ):
        device.power(True)
        with pytest.raises(ValueError, match="type 1-5"):
            device.select_input("71")
        with pytest.raises(DeviceError):
            device.command("AVMT", "41")  # past the driver's checks: the fake refuses it by the table
        assert server.refused == ["%1AVMT 41"]


@pytest.mark.parametrize("vendor", sorted(COMMAND_SETS))
def test_every_serial_frame_a_command_set_builds_is_in_the_table(vendor: str) -> None:
    commands = COMMAND_SETS[vendor]()
    built = {
        "power": {commands.power(True), commands.power(False)},
        "power?": {commands.power_query()},
        "input": {commands.select_input(code) for code in commands.inputs.values()},
        "blank": {commands.blank(True), commands.blank(False)},
    }
    table = {c.operation: set(c.encodings()) for c in SERIAL_COMMANDS if c.vendor == vendor}
    assert built == table


@pytest.mark.parametrize(
    ("vendor", "frame", "refusal"),
    [
        ("benq", b"\r*pow=standby#\r", b"*Illegal format#"),
        ("epson", b"SOURCE 99\r", b"ERR"),
        ("optoma", b"~0000 2\r", b"F"),
    ],
)
def test_the_simulated_serial_projector_refuses_frames_outside_the_table(
    vendor: str, frame: bytes, refusal: bytes
) -> None:
    if SIM_HANDLERS not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(SIM_HANDLERS)
    port = serial.serial_for_url(f"simprojector://{vendor}", timeout=0.5)
    port.write(frame)
    time.sleep(0.05)
    assert refusal in port.read(port.in_waiting or 1)
    port.close()


def test_every_v4l2_control_the_driver_sets_is_the_tables() -> None:
    fake = FakeVideoCapture(V4l2Faults(sizes=((1280, 1024),)))
    camera = V4l2Camera("cam", "fake", (1280, 1024), exposure_us=8000.0, gain=4, capture_factory=lambda _: fake)
    camera.open()
    camera.set_exposure_us(12345.0)
    camera.close()
    assert not fake.refused and {prop for prop, _ in fake.sets} <= set(CONTROLS)
    values = dict(fake.sets)  # the last value set of each
    assert values[cv2.CAP_PROP_AUTO_EXPOSURE] == 1  # V4L2_EXPOSURE_MANUAL, not OpenCV's normalised 0.25
    assert values[cv2.CAP_PROP_EXPOSURE] == 123  # 12345 us in 100 us units, whole
    assert values[cv2.CAP_PROP_FOURCC] == cv2.VideoWriter_fourcc(*"GREY")  # pixelformat, four characters


@pytest.mark.parametrize(
    ("prop", "value"),
    [(cv2.CAP_PROP_AUTO_EXPOSURE, 0.25), (cv2.CAP_PROP_EXPOSURE, 12.5), (cv2.CAP_PROP_BUFFERSIZE, 64), (999, 1)],
)
def test_the_v4l2_fake_refuses_what_the_table_refuses(prop: int, value: float) -> None:
    fake = FakeVideoCapture()
    before = fake.get(prop)
    assert fake.set(prop, value) is False and fake.get(prop) == before and fake.refused
