"""What every power control promises: power, input and blank when open, state errors when not,
and a finite, named failure when the projector stops answering or goes away."""

from __future__ import annotations

import pytest

from drivers.base import PowerControl
from drivers.errors import DeviceError, DeviceStateError
from drivers.faults import Fault
from drivers.testing.kit import FAULT_GRACE_S, Contract, Kit, fails_within


class PowerControlContract(Contract[PowerControl]):
    def test_power_input_and_blank(self, kit: Kit[PowerControl]) -> None:
        control = kit.device
        control.open()
        control.power(True)
        assert control.power_state() in ("on", "warming")
        control.select_input(kit.input_name)
        control.blank(True)
        if kit.is_blanked is not None:
            assert kit.is_blanked()
        control.blank(False)
        if kit.is_blanked is not None:
            assert not kit.is_blanked()

    def test_an_unknown_input_is_refused_by_name(self, kit: Kit[PowerControl]) -> None:
        kit.device.open()
        with pytest.raises(ValueError, match="no-such-input"):
            kit.device.select_input("no-such-input")

    def test_use_after_close_is_a_state_error_and_close_is_idempotent(self, kit: Kit[PowerControl]) -> None:
        with pytest.raises(DeviceStateError):
            kit.device.power(True)
        kit.device.open()
        kit.device.close()
        kit.device.close()
        with pytest.raises(DeviceStateError):
            kit.device.blank(True)

    @pytest.mark.parametrize("fault", [Fault.SILENCE, Fault.DISCONNECT])
    def test_a_fault_fails_within_the_timeout(self, fault: Fault) -> None:
        kit = self.faulty(fault)
        try:

            def use() -> None:
                kit.device.open()
                kit.device.power_state()

            fails_within(kit.timeout_s * 2 + FAULT_GRACE_S, use, DeviceError)
        finally:
            kit.close()
