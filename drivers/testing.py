"""Byte-exact driver tests, PyMeasure style: a port that plays a script of (sent, reply) exchanges.

    with scripted_port([(b":GA#", b"+45\\xdf30'00#")]) as port:
        assert LX200Table(port, az_limits, zen_limits).altitude_deg() == 45.5

The script fails the test when the driver sends anything other than the next expected bytes, and at the end
of the ``with`` block when exchanges are left over or sent bytes are still unmatched.
"""

from __future__ import annotations

from contextlib import contextmanager

from .transport import Port


class ScriptedSerial:
    """A pyserial-like object that checks writes against a script and plays the scripted replies."""

    def __init__(self, exchanges):
        self.script = [(bytes(a), bytes(b)) for a, b in exchanges]
        self.pending = bytearray()  # written, not yet matched
        self.output = bytearray()  # reply bytes to be read
        self.timeout = 0.05
        self.is_open = True

    def write(self, data: bytes) -> int:
        self._unsolicited()  # on a real port, volunteered bytes would already be waiting
        self.pending += data
        while self.script and self.script[0][0] and self.pending.startswith(self.script[0][0]):
            sent, reply = self.script.pop(0)
            del self.pending[: len(sent)]
            self.output += reply
        expected = self.script[0][0] if self.script else b""
        if self.pending and not expected.startswith(bytes(self.pending)):
            raise AssertionError(f"driver sent {bytes(self.pending)!r}, the script expected {expected!r}")
        return len(data)

    def _unsolicited(self) -> None:
        # an exchange with nothing to send is a reply the device volunteers (e.g. APT MOVE_COMPLETED)
        while self.script and self.script[0][0] == b"" and not self.pending:
            self.output += self.script.pop(0)[1]

    def read(self, size: int = 1) -> bytes:
        self._unsolicited()
        data = bytes(self.output[:size])
        del self.output[:size]
        return data

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        self._unsolicited()
        end = self.output.find(expected)
        n = len(self.output) if end < 0 else end + len(expected)
        if size is not None:
            n = min(n, size)
        data = bytes(self.output[:n])
        del self.output[:n]
        return data

    @property
    def in_waiting(self) -> int:
        self._unsolicited()
        return len(self.output)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self.output.clear()

    def close(self) -> None:
        self.is_open = False

    def check_done(self) -> None:
        if self.script:
            raise AssertionError(f"exchanges not used: {self.script!r}")
        if self.pending:
            raise AssertionError(f"sent bytes matched no exchange: {bytes(self.pending)!r}")
        if self.output:
            raise AssertionError(f"reply bytes never read: {bytes(self.output)!r}")


@contextmanager
def scripted_port(exchanges, *, name: str = "scripted", timeout_s: float = 0.05):
    """A :class:`~drivers.transport.Port` over a :class:`ScriptedSerial`; checks the script is used up."""
    raw = ScriptedSerial(exchanges)
    yield Port(raw, name=name, timeout_s=timeout_s)
    raw.check_done()
