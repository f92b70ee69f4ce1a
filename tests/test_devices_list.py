"""`slrig devices`: the inventory of attached hardware."""

from __future__ import annotations

import json
from types import SimpleNamespace
from typing import Any

import pytest

from rig.cli import main
from rig.doctor.inventory import describe, usb_devices


def test_known_usb_devices_are_named() -> None:
    attached = [
        SimpleNamespace(idVendor=0x0451, idProduct=0x6401, bus=1, address=7),
        SimpleNamespace(idVendor=0x1234, idProduct=0x5678, bus=1, address=8),
    ]

    def finder(**kwargs: Any) -> list[SimpleNamespace]:
        assert kwargs == {"find_all": True}
        return attached

    found = usb_devices(finder)
    assert found["devices"][0] == {
        "id": "0451:6401",
        "bus": 1,
        "address": 7,
        "known": "TI DLP LightCrafter 4500 (DLPC350)",
    }
    assert found["devices"][1]["known"] is None
    lines = describe({"usb": found, "video": [], "serial": [], "oak": {"devices": [], "error": "x"}})
    assert any("LightCrafter 4500" in line for line in lines)


def test_usb_listing_without_libusb_says_what_to_install() -> None:
    def broken(**kwargs: Any) -> list[Any]:
        raise RuntimeError("No backend available")

    found = usb_devices(broken)
    assert found["devices"] == [] and "libusb" in found["error"]


def test_devices_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["devices", "--json"]) == 0
    found = json.loads(capsys.readouterr().out)
    assert set(found) == {"usb", "video", "serial", "oak"}
    assert isinstance(found["video"], list) and isinstance(found["serial"], list)
