"""Typed errors of the device layer. Each carries the device's name and, where bytes were involved, the
bytes actually received, so a log shows what the device said."""

from __future__ import annotations


class DeviceError(Exception):
    """Base class of every device error.

    Attributes
    ----------
    device : str
        Name of the device (usually its port URL).
    received : bytes
        Bytes received in the failed exchange (may be empty).
    """

    def __init__(self, device: str, message: str, *, received: bytes = b""):
        self.device = device
        self.received = bytes(received)
        detail = f" (received {self.received!r})" if self.received else ""
        super().__init__(f"{device}: {message}{detail}")


class DeviceTimeout(DeviceError):
    """No complete reply within the timeout; `received` holds any partial reply."""


class ProtocolError(DeviceError):
    """A reply that does not parse: wrong frame, bad checksum, unexpected answer."""


class DeviceDisconnected(DeviceError):
    """The port went away (unplugged cable, closed socket, dead simulator)."""


class DeviceFault(DeviceError):
    """The device reports a fault: limit switch, lamp fault, motion error, over-temperature."""


class LimitError(DeviceError, ValueError):
    """A request outside the configured limits, refused before anything was sent."""
