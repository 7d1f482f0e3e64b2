"""Driver of a generic SCPI bench power supply that drives the LED string of the LED sun simulator.

Command subset (anchors-protocols §4.2, from RTS2 ``agilent-e3631a.cpp``): ``*IDN?``, ``SYST:REM``,
``APPL [<output>,]<V>,<A>``, ``CURR <A>`` / ``CURR?``, ``OUTP ON|OFF``, ``OUTP?``, ``MEAS:CURR?``,
``MEAS:VOLT?``, ``SYST:ERR?`` (code 0 means no error: ``0,"No error"`` as SCPI-99 writes it, ``+0,"No error"``
as Keysight supplies do; both are read). Every set is followed by ``SYST:ERR?``; an error in the queue raises
:class:`ScpiError` with its code and text, after the queue has been read empty so the next check starts clean.
Each command goes in a message of its own, so the SCPI path rules of ``;`` compounds never apply to it.

Line framing, and why:

* Commands end with LF (``\\n``): the IEEE-488.2 program-message terminator, and what the Agilent E363xA
  manual asks for over RS-232 ("a <new line> must terminate the command string").
* Replies are read up to LF, and a CR before it is dropped, so a supply that answers CR LF works unchanged.
* Line settings are the caller's ``open_port`` arguments. For the Agilent/Keysight E363xA family the manual
  gives 9600 baud, 8 data bits, no parity, **2 stop bits**, DTR/DSR handshake (:data:`E363XA_SERIAL`);
  anchors-protocols §4.2 lists the RS-232 settings of SCPI supplies as UNCONFIRMED, so check the supply
  actually used.

The LED needs no mechanical shutter: with the output off the LED is dark, so the output *is* the shutter of
the LED source (:class:`drivers.sources.LedSource`).

Queries are retried once after a garbled or cut reply — except ``SYST:ERR?``, which pops the entry it
reads; sets are never re-sent.
"""

from __future__ import annotations

import logging
import math
import time

from .errors import LimitError, ProtocolError
from .scpi_protocol import NUMBER, ScpiError, ScpiErrorQueue  # noqa: F401 - ScpiError re-exported
from .transport import Port, ask_again

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TERMINATOR = b"\n"
# Agilent E363xA RS-232 (user's guide, "RS-232 Interface Configuration"): pass as open_port(**E363XA_SERIAL)
E363XA_SERIAL = {"baudrate": 9600, "bytesize": 8, "parity": "N", "stopbits": 2, "dsrdtr": True}



class ScpiSupply(ScpiErrorQueue):
    """A SCPI bench power supply used as a constant-current LED driver.

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, **E363XA_SERIAL)`` or the settings of the supply used.
    max_current_a : float
        Highest current setpoint this driver sends [A] (the LED string's rating); larger requests raise
        :class:`~drivers.errors.LimitError` before anything is sent.
    max_voltage_v : float
        Highest voltage (compliance) setpoint this driver sends [V].
    output : str, optional
        Output name for ``APPL`` and ``MEAS`` on a multi-output supply (``"P6V"`` on an E3631A); None for a
        single-output supply.
    retries : int
        How many times a *query* is asked again after a garbled or cut reply.
    clock : callable
        Time source [s] for :attr:`output_on_at_s` (``time.monotonic``; a simulated bench passes
        ``SimClock.now``).
    name : str, optional

    Attributes
    ----------
    output_on_at_s : float or None
        `clock` time of the last ``OUTP ON`` this driver sent, None after ``OUTP OFF`` [s].
    """

    def __init__(self, port: Port, *, max_current_a: float, max_voltage_v: float, output: str | None = None,
                 retries: int = 1, clock=time.monotonic, name: str | None = None):
        self.port = port
        self.name = name or port.name
        self.max_current_a = float(max_current_a)
        self.max_voltage_v = float(max_voltage_v)
        self.output = output
        self.retries = int(retries)
        self.clock = clock
        self.output_on_at_s: float | None = None

    # -- exchanges ------------------------------------------------------------------------------------
    def _write(self, command: str) -> None:
        with self.port.transaction():
            self.port.discard_input()
            self.port.write(command.encode("ascii") + TERMINATOR)

    def _ask(self, command: str, parse, *, retry: bool = True):
        def attempt():
            reply = self.port.query(command.encode("ascii") + TERMINATOR, TERMINATOR)
            return parse(command, reply[:-1].removesuffix(b"\r").decode("ascii", errors="replace"))

        return ask_again(self.name, attempt, self.retries if retry else 0)

    def _float(self, command: str, text: str) -> float:
        if not NUMBER.match(text):
            raise ProtocolError(self.name, f"{command!r}: expected a number, got {text!r}")
        return float(text)

    def _set(self, command: str) -> None:
        """Send a set and read the error queue empty; errors raise :class:`ScpiError`."""
        self._write(command)
        self.check_errors(command)

    def _suffix(self) -> str:
        return f" {self.output}" if self.output else ""

    def _check_current(self, current_a: float) -> float:
        current_a = float(current_a)
        if not (math.isfinite(current_a) and 0.0 <= current_a <= self.max_current_a):
            raise LimitError(self.name, f"current {current_a} A is outside [0, {self.max_current_a}] A")
        return current_a

    def _check_voltage(self, voltage_v: float) -> float:
        voltage_v = float(voltage_v)
        if not (math.isfinite(voltage_v) and 0.0 <= voltage_v <= self.max_voltage_v):
            raise LimitError(self.name, f"voltage {voltage_v} V is outside [0, {self.max_voltage_v}] V")
        return voltage_v

    # -- errors ---------------------------------------------------------------------------------------
    # -- identity -------------------------------------------------------------------------------------
    def identify(self) -> str:
        """Get the identification (``*IDN?`` → maker, model, serial, firmware)."""
        def parse(command, text):
            if text.count(",") != 3 or not text.isprintable():
                raise ProtocolError(self.name, f"{command!r}: expected four comma-separated fields, got {text!r}")
            return text
        return self._ask("*IDN?", parse)

    def remote(self) -> None:
        """Put the supply in remote mode (``SYST:REM``), which the E363xA needs before RS-232 commands."""
        self._set("SYST:REM")

    # -- setpoints ------------------------------------------------------------------------------------
    def apply(self, voltage_v: float, current_a: float) -> None:
        """Set voltage [V] and current [A] together (``APPL [P6V,]5.000,0.700``); both checked first."""
        voltage_v, current_a = self._check_voltage(voltage_v), self._check_current(current_a)
        prefix = f"{self.output}," if self.output else ""
        self._set(f"APPL {prefix}{voltage_v:.3f},{current_a:.3f}")

    def set_current_a(self, current_a: float) -> None:
        """Set the current setpoint [A] (``CURR 0.700``), checked against `max_current_a` first."""
        current_a = self._check_current(current_a)
        self._set(f"CURR {current_a:.3f}")

    def current_setpoint_a(self) -> float:
        """Get the current setpoint [A] (``CURR?``)."""
        return self._ask("CURR?", self._float)

    # -- output ---------------------------------------------------------------------------------------
    def set_output(self, on: bool) -> None:
        """Switch the output on or off (``OUTP ON`` / ``OUTP OFF``); for the LED this is its shutter."""
        self._set("OUTP ON" if on else "OUTP OFF")
        if not on:
            self.output_on_at_s = None
        elif self.output_on_at_s is None:  # switching on an output that is on does not restart the LED
            self.output_on_at_s = self.clock()

    def output_enabled(self) -> bool:
        """Get whether the output is on (``OUTP?`` → 1 or 0).

        Also keeps :attr:`output_on_at_s` true to the supply: cleared when the output is off, and set to now
        when the output is found on without this driver having switched it on (the conservative guess).
        """
        def parse(command, text):
            if text not in ("0", "1"):
                raise ProtocolError(self.name, f"{command!r}: expected 0 or 1, got {text!r}")
            return text == "1"
        on = self._ask("OUTP?", parse)
        if not on:
            self.output_on_at_s = None
        elif self.output_on_at_s is None:
            self.output_on_at_s = self.clock()
        return on

    # -- measurements ---------------------------------------------------------------------------------
    def measure_current_a(self) -> float:
        """Measure the output current [A] (``MEAS:CURR?``)."""
        return self._ask(f"MEAS:CURR?{self._suffix()}", self._float)

    def measure_voltage_v(self) -> float:
        """Measure the output voltage [V] (``MEAS:VOLT?``)."""
        return self._ask(f"MEAS:VOLT?{self._suffix()}", self._float)
