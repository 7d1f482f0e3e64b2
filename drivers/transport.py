"""Ports opened by URL, and the one query helper every driver uses.

A driver never opens a port from a hard-coded name: it gets a :class:`Port` built from a URL by
:func:`open_port` — a real port (``/dev/ttyUSB0``), ``socket://host:port`` (a simulator in another
process), ``sim://NAME`` (an in-process simulator) — so real and simulated devices differ only in the URL.
``record=`` wraps the port in a :class:`RecordingSerial` that logs every byte both ways.

The :class:`Port` rules (research note anchors-orchestration, lesson 6): explicit terminators per call,
a timeout on every read, one lock per port, typed errors that carry the bytes received.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import serial

from .errors import DeviceDisconnected, DeviceError, DeviceTimeout, ProtocolError

log = logging.getLogger(__name__)
_SIM_PACKAGE = "drivers.sim.urlhandler"


def register_sim_scheme() -> None:
    """Make ``sim://NAME`` URLs open in-process simulators (pyserial protocol handler package)."""
    if _SIM_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(_SIM_PACKAGE)


def open_port(url: str, *, baudrate: int = 9600, timeout_s: float = 1.0, record=None, name: str | None = None,
              **settings) -> Port:
    """Open a port by URL and wrap it in a :class:`Port`.

    Parameters
    ----------
    url : str
        ``/dev/ttyUSB0``, ``COM3``, ``socket://127.0.0.1:9101``, ``sim://table`` …
    baudrate : int
        Line speed of the device [baud].
    timeout_s : float
        Read timeout of every read [s].
    record : path-like or list, optional
        Log every write and read: a JSONL file path, or a list to append event dicts to.
    name : str, optional
        Name used in errors; default the URL.
    settings
        Other pyserial settings (``rtscts``, ``xonxoff``, ``bytesize``, ``parity``, ``stopbits``).
    """
    register_sim_scheme()
    try:
        raw = serial.serial_for_url(url, baudrate=baudrate, timeout=timeout_s, write_timeout=timeout_s, **settings)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise DeviceDisconnected(name or url, f"cannot open port ({exc})") from None
    if record is not None:
        raw = RecordingSerial(raw, record)
    return Port(raw, name=name or url, timeout_s=timeout_s)


#: Retries after a bad exchange on the binary links (APT, CMOS module). Line noise spoils one reply now and
#: then; four bad replies in a row mean the link or the device is broken, and the run should stop and say so.
DEFAULT_RETRIES = 3


def ask_again(name: str, attempt, retries: int, *, on=(ProtocolError, DeviceTimeout), on_retry=None):
    """Call `attempt()`; after a garbled, cut or late reply (`on`) call it again, up to `retries` more times.

    Only for exchanges that are safe to repeat (queries, sets of an absolute value): a command that may
    have taken effect and would act again (a relative move, a toggle) must not be re-sent. `on_retry(exc)`
    is called before each retry (drivers count them). The last failure is raised with its own type, so a
    caller still tells a timeout from a malformed reply from a bad CRC, and with
    :attr:`~drivers.errors.DeviceError.attempts` set, so its message says the link was retried.
    """
    for left in range(retries, -1, -1):
        try:
            return attempt()
        except on as exc:
            if not left:
                exc.attempts = retries + 1
                raise
            log.warning("%s; asking again", exc if isinstance(exc, DeviceError) else f"{name}: {exc}")
            if on_retry is not None:
                on_retry(exc)


class Port:
    """A serial-like port with a lock, timeouts and typed errors.

    Every read has a deadline; a read that ends early raises :class:`DeviceTimeout` carrying what did
    arrive. Serial or OS errors become :class:`DeviceDisconnected`. Drivers hold :meth:`transaction`
    around a write and its reply so two threads never interleave on one port.
    """

    def __init__(self, raw, *, name: str, timeout_s: float = 1.0):
        self.raw = raw
        self.name = name
        self.timeout_s = timeout_s
        self.lock = threading.RLock()

    @contextmanager
    def transaction(self):
        with self.lock:
            yield self

    @contextmanager
    def _io(self, received: bytearray | None = None):
        try:
            yield
        except (serial.SerialException, OSError) as exc:
            raise DeviceDisconnected(self.name, f"port error ({exc})", received=bytes(received or b"")) from None

    def write(self, data: bytes) -> None:
        with self._io():
            self.raw.write(data)
            self.raw.flush()

    def discard_input(self) -> bytes:
        """Drop (and return) whatever is waiting, so a reply cannot be taken for an older one."""
        return self.read_available()

    def read_available(self) -> bytes:
        """Whatever has already arrived, without waiting (a binary reader looks at what follows a frame)."""
        dropped = bytearray()
        with self._io(dropped):
            # loop: some ports (pyserial's socket://) report 1 for "something is waiting", not a count
            for _ in range(10000):
                waiting = self.raw.in_waiting
                if not waiting:
                    break
                dropped += self.raw.read(waiting)
        return bytes(dropped)

    def read_exact(self, size: int, *, timeout_s: float | None = None) -> bytes:
        """Read exactly `size` bytes or raise :class:`DeviceTimeout` with the partial reply."""
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        data = bytearray()
        with self._io(data):
            while len(data) < size:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self.raw.timeout = left
                data += self.raw.read(size - len(data))
        if len(data) < size:
            raise DeviceTimeout(self.name, f"expected {size} bytes, got {len(data)}", received=bytes(data))
        return bytes(data)

    def read_until(self, terminator: bytes, *, max_bytes: int = 4096, timeout_s: float | None = None) -> bytes:
        """Read up to and including `terminator`; raise :class:`DeviceTimeout` with the partial reply."""
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        data = bytearray()
        with self._io(data):
            while not data.endswith(terminator):
                left = deadline - time.monotonic()
                if left <= 0 or len(data) >= max_bytes:
                    break
                self.raw.timeout = left
                chunk = self.raw.read_until(terminator, max_bytes - len(data))
                data += chunk
        if not data.endswith(terminator):
            why = "reply too long" if len(data) >= max_bytes else f"no {terminator!r} terminator within the timeout"
            raise DeviceTimeout(self.name, why, received=bytes(data))
        return bytes(data)

    def query(self, command: bytes, terminator: bytes, *, max_bytes: int = 4096,
              timeout_s: float | None = None) -> bytes:
        """Discard stale input, send `command`, return the reply up to and including `terminator`."""
        with self.transaction():
            self.discard_input()
            self.write(command)
            return self.read_until(terminator, max_bytes=max_bytes, timeout_s=timeout_s)

    def close(self) -> None:
        try:
            self.raw.close()
        except (serial.SerialException, OSError):
            pass


class RecordingSerial:
    """Wraps a pyserial port and logs every byte written and read, for recording sessions.

    Events are dicts ``{"t": seconds, "dir": "tx"|"rx", "hex": "…"}``; they go to a list or, one JSON
    object per line, to a file. :meth:`exchanges` pairs them into ``(sent, reply)`` tuples, the form the
    byte-exact driver tests use.
    """

    def __init__(self, raw, sink):
        self._raw = raw
        self._t0 = time.monotonic()
        if isinstance(sink, list):
            self.events, self._file = sink, None
        else:
            self.events, self._file = [], Path(sink).open("a", buffering=1)

    def _log(self, direction: str, data: bytes) -> None:
        if not data:
            return
        event = {"t": round(time.monotonic() - self._t0, 6), "dir": direction, "hex": bytes(data).hex()}
        self.events.append(event)
        if self._file:
            self._file.write(json.dumps(event) + "\n")

    def write(self, data):
        n = self._raw.write(data)
        self._log("tx", bytes(data))
        return n

    def read(self, size=1):
        data = self._raw.read(size)
        self._log("rx", data)
        return data

    def read_until(self, expected=b"\n", size=None):
        data = self._raw.read_until(expected, size)
        self._log("rx", data)
        return data

    def close(self):
        self._raw.close()
        if self._file:
            self._file.close()

    def exchanges(self) -> list[tuple[bytes, bytes]]:
        """The log as ``(sent, reply)`` pairs: each write with the bytes read until the next write."""
        pairs: list[list[bytes]] = []
        for e in self.events:
            data = bytes.fromhex(e["hex"])
            if e["dir"] == "tx":
                pairs.append([data, b""])
            elif pairs:
                pairs[-1][1] += data
            else:
                pairs.append([b"", data])
        return [(a, b) for a, b in pairs]

    def __getattr__(self, name):
        return getattr(self._raw, name)

    def __setattr__(self, name, value):
        if name.startswith("_") or name in ("events",):
            object.__setattr__(self, name, value)
        else:
            setattr(self._raw, name, value)
