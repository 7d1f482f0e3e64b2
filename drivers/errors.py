"""Typed errors of the device layer. Each carries the device's name and, where bytes were involved, the
bytes actually received, so a log shows what the device said.

A bad exchange is one of three kinds, and the retry helper (:func:`drivers.transport.ask_again`) keeps the
kind of the last one: :class:`DeviceTimeout` (silence, or a reply that stopped coming), :class:`ProtocolError`
(a malformed reply) and its :class:`ChecksumError` (a whole frame whose CRC does not match)."""

from __future__ import annotations


class DeviceError(Exception):
    """Base class of every device error.

    Attributes
    ----------
    device : str
        Name of the device (usually its port URL).
    received : bytes
        Bytes received in the failed exchange (may be empty).
    attempts : int
        Exchanges tried before giving up (1 unless the error ended a run of retries).
    """

    attempts: int = 1  # set by ask_again when it gives up, so the message says the link was retried

    def __init__(self, device: str, message: str, *, received: bytes = b""):
        self.device = device
        self.received = bytes(received)
        detail = f" (received {self.received!r})" if self.received else ""
        super().__init__(f"{device}: {message}{detail}")

    def __str__(self) -> str:
        text = super().__str__()
        return f"{text} [gave up after {self.attempts} attempts]" if self.attempts > 1 else text


class DeviceTimeout(DeviceError):
    """No complete reply within the timeout; `received` holds any partial reply."""


class ProtocolError(DeviceError):
    """A reply that does not parse: wrong frame, bad checksum, unexpected answer."""


class ChecksumError(ProtocolError):
    """A frame that arrived whole but whose checksum (CRC) does not match: noise on the line."""


class DeviceDisconnected(DeviceError):
    """The port went away (unplugged cable, closed socket, dead simulator)."""


class DeviceFault(DeviceError):
    """The device reports a fault: limit switch, lamp fault, motion error, over-temperature."""


class LimitError(DeviceError, ValueError):
    """A request outside the configured limits, refused before anything was sent."""
