"""What the SCPI-style instruments share (IEEE 488.2 / SCPI-99): the error queue read with ``SYST:ERR?`` until it
answers ``0,"No error"``, and the number a query answers. The LED supply (:mod:`drivers.scpi_supply`) and the IR Earth
simulator's controller (:mod:`drivers.earth_simulator`) both read their queue after every set."""

from __future__ import annotations

import re

from .errors import DeviceError, ProtocolError

#: A query's plain decimal number (NR1/NR2/NR3)
NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")
#: An error queue entry, ``<code>,"<message>"``
ERROR_ENTRY = re.compile(r'^([+-]?\d+),"([^"]*)"$')
#: A SCPI error queue holds a few dozen entries at most; stop reading after that many
MAX_ERRORS = 20


class ScpiError(DeviceError):
    """The instrument's error queue was not empty after a command.

    Attributes
    ----------
    errors : list of (int, str)
        Every (code, message) read from the queue, oldest first.
    command : str
    """

    def __init__(self, device: str, command: str, errors: list[tuple[int, str]]):
        self.errors = errors
        self.command = command
        text = "; ".join(f"{code} {message}" for code, message in errors)
        super().__init__(device, f"after {command!r}: {text}")


class ScpiErrorQueue:
    """The error queue of a driver that has ``name`` and ``_ask(command, parse, retry=…)``; `queue_error` is the
    :class:`ScpiError` subclass it raises."""

    name: str
    queue_error: type[ScpiError] = ScpiError

    def next_error(self) -> tuple[int, str]:
        """Get the oldest entry of the error queue (``SYST:ERR?`` → ``+0,"No error"``).

        Not asked again after a bad reply: the read took the entry off the queue, a second read would lose it.
        """
        def parse(command, text):
            match = ERROR_ENTRY.match(text)
            if not match:
                raise ProtocolError(self.name, f"{command!r}: expected <code>,\"<message>\", got {text!r}")
            return int(match.group(1)), match.group(2)
        return self._ask("SYST:ERR?", parse, retry=False)

    def check_errors(self, command: str = "the last command") -> None:
        """Read the error queue until it is empty; raise :attr:`queue_error` if it held anything."""
        errors = []
        for _ in range(MAX_ERRORS):
            code, message = self.next_error()
            if code == 0:
                break
            errors.append((code, message))
        if errors:
            raise self.queue_error(self.name, command, errors)
