"""The one exception hierarchy for device faults."""

from __future__ import annotations


class DeviceError(Exception):
    """A device failed an operation. Raise a subclass when one fits; this base only for faults
    that are none of them (for example a device that reports an internal error code)."""


class DeviceNotFoundError(DeviceError):
    """Raised when opening a device whose port, USB id, serial number or index does not exist."""


class DeviceStateError(DeviceError):
    """Raised when an operation does not fit the device's state: used before open() or after
    close(), or a software trigger on a device set to wait for hardware triggers. A caller error,
    not a fault of the device."""


class DeviceTimeoutError(DeviceError, TimeoutError):
    """Raised when a device does not answer, or a frame does not arrive, within its named timeout."""


class DeviceDisconnectedError(DeviceError, ConnectionError):
    """Raised when a device that was open disappears (cable pulled, USB reset, port closed)."""


class DeviceProtocolError(DeviceError):
    """Raised when a reply is malformed or does not match the command sent (wrong echo, bad
    checksum, unexpected length)."""


class DeviceAuthenticationError(DeviceError):
    """Raised when a device refuses the credentials it was given, or asks for some and none were
    configured (a PJLink password)."""


class DeviceCancelledError(DeviceError):
    """Raised when a wait for a device (a frame) is cut short because the caller cancelled it: the
    `cancel` Event given to Camera.capture was set. Not a fault of the device."""
