"""``sim://NAME``: a pyserial port whose other end is an in-process simulator.

Writes go to the simulator's protocol front, its replies (and what it volunteers as simulated time passes)
come back through a byte buffer. Reads honour pyserial's timeout semantics, so drivers see exactly what a
real port would give them — including nothing at all.
"""

from __future__ import annotations

import threading
import time
import urllib.parse

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from .. import registry

_POLL_S = 0.0005  # how often a blocked read asks the simulator for volunteered output


class Serial(SerialBase):
    """pyserial port for ``sim://NAME`` URLs."""

    BAUDRATES = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)

    def open(self):
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        parts = urllib.parse.urlsplit(self.port)
        if parts.scheme != "sim":
            raise SerialException(f"expected sim://NAME, got {self.port!r}")
        try:
            self._device = registry.lookup(parts.netloc or parts.path.lstrip("/"))
        except KeyError as exc:
            raise SerialException(str(exc)) from None
        if self._device.faults.disconnected:
            raise SerialException(f"{self.port}: device not connected")
        self._buffer = bytearray()
        self._cond = threading.Condition()
        self._device.reset_link()
        self.is_open = True

    def close(self):
        self.is_open = False
        super().close()

    def _reconfigure_port(self):
        pass

    def _update_rts_state(self):
        pass

    def _update_dtr_state(self):
        pass

    def _check(self):
        if not self.is_open:
            raise PortNotOpenError()
        if self._device.faults.disconnected:
            raise SerialException(f"{self.port}: device disconnected")

    def _pull(self):
        data = self._device.poll()
        if data:
            self._buffer += data

    @property
    def in_waiting(self):
        self._check()
        self._pull()
        return len(self._buffer)

    def read(self, size=1):
        self._check()
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        while True:
            self._pull()
            if len(self._buffer) >= size or (self._timeout == 0):
                break
            if deadline is not None and time.monotonic() >= deadline:
                break
            time.sleep(_POLL_S)
            self._check()
        data = bytes(self._buffer[:size])
        del self._buffer[:size]
        return data

    def read_until(self, expected=b"\n", size=None):
        self._check()
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        while True:
            self._pull()
            end = self._buffer.find(expected)
            if end >= 0 or (size is not None and len(self._buffer) >= size) or self._timeout == 0:
                break
            if deadline is not None and time.monotonic() >= deadline:
                break
            time.sleep(_POLL_S)
            self._check()
        n = len(self._buffer) if end < 0 else end + len(expected)
        if size is not None:
            n = min(n, size)
        data = bytes(self._buffer[:n])
        del self._buffer[:n]
        return data

    def write(self, data):
        self._check()
        data = bytes(data)
        reply = self._device.receive(data)
        if reply:
            self._buffer += reply
        return len(data)

    def flush(self):
        self._check()

    def reset_input_buffer(self):
        self._check()
        self._pull()
        self._buffer.clear()

    def reset_output_buffer(self):
        self._check()

    @property
    def cts(self):
        return True

    @property
    def dsr(self):
        return True

    @property
    def ri(self):
        return False

    @property
    def cd(self):
        return True
