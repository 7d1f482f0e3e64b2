"""The protocol front every simulator shares: bytes in, bytes out, and a fault back door."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field


@dataclass
class WireFaults:
    """Faults of the link, set through the back door (never reachable over the wire).

    Attributes
    ----------
    no_reply : bool
        The device swallows every command and answers nothing (timeouts).
    garble : int
        The next `garble` replies arrive with their bytes corrupted.
    truncate : int
        The next `truncate` replies arrive cut in half.
    disconnected : bool
        The cable is pulled: every read and write fails.
    """

    no_reply: bool = False
    garble: int = 0
    truncate: int = 0
    disconnected: bool = False

    def filter(self, reply: bytes) -> bytes:
        if not reply or self.no_reply:
            return b""
        if self.garble > 0:
            self.garble -= 1
            # flip the low bits of every other byte, keep the length: a noisy line, not a missing one
            reply = bytes(b ^ 0x5A if i % 2 == 0 else b for i, b in enumerate(reply))
        if self.truncate > 0:
            self.truncate -= 1
            reply = reply[: max(1, len(reply) // 2)]
        return reply

    def clear(self) -> None:
        self.no_reply, self.garble, self.truncate, self.disconnected = False, 0, 0, False


class SimDevice:
    """Base class of a simulated device's protocol front.

    Subclasses implement :meth:`handle`, which consumes complete frames from the input buffer and returns
    the reply bytes, and may implement :meth:`unsolicited` for output the device volunteers as simulated
    time passes (e.g. Thorlabs APT "move completed"). The ``sim://`` port calls :meth:`receive` on every
    write and :meth:`poll` before every read.
    """

    name = "device"

    def __init__(self) -> None:
        self.faults = WireFaults()
        self.inbuf = bytearray()
        self.lock = threading.RLock()

    def receive(self, data: bytes) -> bytes:
        with self.lock:
            self.inbuf += data
            return self.faults.filter(self.handle(self.inbuf))

    def poll(self) -> bytes:
        with self.lock:
            return self.faults.filter(self.unsolicited())

    def handle(self, inbuf: bytearray) -> bytes:  # pragma: no cover - abstract
        raise NotImplementedError

    def unsolicited(self) -> bytes:
        return b""

    def reset_link(self) -> None:
        """Forget half-received input (a new connection)."""
        with self.lock:
            self.inbuf.clear()


class LineDevice(SimDevice):
    """A device with a line protocol: commands end with `in_terminator`, handled one at a time."""

    in_terminator = b"\r"

    def handle(self, inbuf: bytearray) -> bytes:
        out = bytearray()
        while True:
            end = inbuf.find(self.in_terminator)
            if end < 0:
                break
            line = bytes(inbuf[:end])
            del inbuf[: end + len(self.in_terminator)]
            out += self.handle_line(line)
        return bytes(out)

    def handle_line(self, line: bytes) -> bytes:  # pragma: no cover - abstract
        raise NotImplementedError


@dataclass
class ChannelFaults:
    """Faults of a sensor module's channels, through the back door, keyed by the module's own channel names (the QD
    module's quadrant numbers 1 … 4, the CSS head's ``px_uv`` …).

    Attributes
    ----------
    stuck : dict
        The channel's ADC repeats this code whatever the light.
    dead : set
        The detector is open: the channel reads its pedestal (or front end's offset) and noise only.
    saturated : set
        The amplifier is latched at its rail: the channel reads full scale.
    """

    stuck: dict = field(default_factory=dict)
    dead: set = field(default_factory=set)
    saturated: set = field(default_factory=set)

    def clear(self) -> None:
        self.stuck.clear()
        self.dead.clear()
        self.saturated.clear()
