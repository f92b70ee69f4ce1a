"""A rig's hold on a projector's power control (PJLink, RS-232; built by the driver table): the
projector switched on with its input selected while the rig is open, blanked when it closes."""

from __future__ import annotations

from drivers.base import Device, PowerControl


class ProjectorPower(Device):
    """A rig's hold on a projector's power control: switched on with its input selected when
    opened, blanked when closed."""

    def __init__(self, control: PowerControl, input_name: str | None) -> None:
        super().__init__(control.name)
        self.control = control
        self.input_name = input_name

    def _do_open(self) -> None:
        self.control.open()
        try:
            self.control.power(True)
            if self.input_name:
                self.control.select_input(self.input_name)
        except Exception:
            self.control.close()
            raise

    def _do_close(self) -> None:
        try:
            self.control.blank(True)
        finally:
            self.control.close()
