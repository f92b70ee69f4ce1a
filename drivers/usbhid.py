"""A USB HID transport over pyusb: 64-byte reports on interrupt endpoints, finite timeouts, and
libusb errors mapped onto the device error hierarchy."""

from __future__ import annotations

import errno
from collections.abc import Callable
from typing import Any, Protocol

from drivers.errors import DeviceDisconnectedError, DeviceError, DeviceNotFoundError, DeviceTimeoutError

REPORT_SIZE = 64


class HidTransport(Protocol):
    """What a HID device driver needs: whole reports out and in, each with a deadline."""

    def write(self, report: bytes, timeout_s: float) -> None: ...

    def read(self, timeout_s: float) -> bytes: ...

    def close(self) -> None: ...


def _translate(exc: Exception, what: str) -> DeviceError:
    code = getattr(exc, "errno", None)
    if code == errno.ETIMEDOUT:
        return DeviceTimeoutError(f"{what}: no answer within the timeout")
    if code in (errno.ENODEV, errno.ENOENT, errno.EPIPE, errno.EIO):
        return DeviceDisconnectedError(f"{what}: device gone ({exc})")
    if code == errno.EBUSY:
        return DeviceError(f"{what}: device busy (another program has it open?)")
    if code in (errno.EACCES, errno.EPERM):
        return DeviceError(f"{what}: permission denied; add the udev rule from systemd/ (and the plugdev group)")
    return DeviceError(f"{what}: USB error: {exc}")


class PyUsbHidTransport:
    """Interface 0 of the first USB device with `vendor_id`:`product_id`, claimed from the kernel's
    usbhid driver (and given back on close). `finder` is `usb.core.find`, injectable for tests."""

    def __init__(
        self,
        vendor_id: int,
        product_id: int,
        serial_number: str | None = None,
        out_endpoint: int = 0x01,
        in_endpoint: int = 0x81,
        finder: Callable[..., Any] | None = None,
    ) -> None:
        import usb.core  # imported here: pyusb is needed only by USB devices

        self._usb_error = usb.core.USBError
        find = finder or usb.core.find
        self.name = f"usb {vendor_id:04x}:{product_id:04x}"
        kwargs: dict[str, Any] = {"idVendor": vendor_id, "idProduct": product_id}
        if serial_number is not None:
            kwargs["serial_number"] = serial_number
        try:
            device = find(**kwargs)
        except Exception as exc:  # NoBackendError and friends: no libusb on this machine
            raise DeviceNotFoundError(f"{self.name}: cannot search USB ({exc}); install libusb-1.0") from exc
        if device is None:
            raise DeviceNotFoundError(f"{self.name}: not attached (check the cable and `slrig devices`)")
        self._device = device
        self._out, self._in = out_endpoint, in_endpoint
        self._reattach = False
        try:
            if device.is_kernel_driver_active(0):
                device.detach_kernel_driver(0)
                self._reattach = True
            device.set_configuration()
            import usb.util

            usb.util.claim_interface(device, 0)
        except self._usb_error as exc:
            raise _translate(exc, f"{self.name}: open") from exc

    def write(self, report: bytes, timeout_s: float) -> None:
        if len(report) != REPORT_SIZE:
            raise ValueError(f"HID reports are {REPORT_SIZE} bytes, got {len(report)}")
        try:
            written = self._device.write(self._out, report, max(1, int(timeout_s * 1000)))
        except self._usb_error as exc:
            raise _translate(exc, f"{self.name}: write") from exc
        if written != REPORT_SIZE:
            raise DeviceError(f"{self.name}: short write ({written} of {REPORT_SIZE} bytes)")

    def read(self, timeout_s: float) -> bytes:
        try:
            data = self._device.read(self._in, REPORT_SIZE, max(1, int(timeout_s * 1000)))
        except self._usb_error as exc:
            raise _translate(exc, f"{self.name}: read") from exc
        return bytes(data)

    def close(self) -> None:
        import usb.util

        try:
            usb.util.release_interface(self._device, 0)
            if self._reattach:
                self._device.attach_kernel_driver(0)
            usb.util.dispose_resources(self._device)
        except self._usb_error:
            pass  # closing a device that is gone: nothing left to give back
