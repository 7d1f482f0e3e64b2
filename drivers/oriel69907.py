"""Driver of the Newport/Oriel 69907 (OPS-A) arc-lamp power supply that feeds the xenon lamp of the sun
simulator (seed 002 used a xenon discharge lamp).

Protocol (research note anchors-protocols §4.1; two independent public drivers, lantz ``newport69907.py``
and RTS2 ``newport-lamp.cpp``, agree on it):

* 9600 baud, 8N1, no handshake; every command and every reply ends with CR (``\\r``).
* Query ``NAME?\\r`` → ``value\\r``; the status registers answer with their name in front:
  ``STB?\\r`` → ``STB81\\r``, ``ESR?\\r`` → ``ESR00\\r`` (two hex digits).
* Set ``NAME=value\\r`` and action ``START\\r`` / ``STOP\\r`` → ``ESRxx\\r``: the event status register,
  which this driver decodes after *every* set or action; a command, execution, device-dependent or query
  error bit raises :class:`Oriel69907Error` carrying the register value.
* ``A-PRESET=5.5`` is sent with one decimal (lantz and RTS2 agree); ``P-PRESET=0095`` zero-padded to four
  digits (lantz; RTS2 sends a plain integer — a zero-padded value also parses as a plain one, the reverse is
  not sure, so the padded form is the safer choice). The limits go the same way: ``A-LIM=12.0``,
  ``P-LIM=0100`` (lantz); ``RST`` restores the factory settings (lantz ``reset``).
* The supply never drives the lamp past ``A-LIM`` or ``P-LIM``: a preset beyond them runs at the limit and
  lights STB bit 1 ("limit") — :attr:`StatusByte.limit` tells that the lamp is not at its preset.

Bits are decoded with masks, never with ``>`` comparisons (lantz's comparisons mis-handle exact powers of
two, §4.1). STB: 7 lamp on, 6 external control, 5 power mode (clear = current mode), 4 calibration mode,
3 fault, 2 communication (front-panel lock on the 69920), 1 limit, 0 interlock. ESR (IEEE-488.2 style):
7 power on, 6 user request, 5 command error, 4 execution error, 3 device-dependent error, 2 query error,
1 request control, 0 operation complete.

**UNCONFIRMED / CONFLICT** (anchors-protocols §4.1, §7 item 8):

* Polarity of STB bit 0. lantz only names the bit "Interlock" (its front-panel LED); the driver of the
  sibling 69920 supply treats bit 0 = 0 as an interlock *error*. This driver follows the 69920 reading by
  default (bit set = interlock closed, safe) and takes ``interlock_bit_set_means_closed=False`` for the
  other reading. Settle it on the hardware.
* Exact widths and formats of the replies (``AMPS?`` float, ``VOLTS?`` float in lantz / integer in RTS2,
  ``WATTS?`` and ``LAMP HRS?`` integers, ``IDN?`` text that RTS2 parses as an integer): the parsers accept
  any plain decimal number and reject anything else.
* What the supply answers to an unknown query; a reply ``ESRxx`` where a value was expected is decoded and
  raised as :class:`Oriel69907Error`.

Queries are retried once after a garbled or cut reply (asking again cannot change the supply) — except
``ESR?``, which clears the register it reads; sets and actions are never re-sent, since the driver cannot
tell whether the first one took effect.
"""

from __future__ import annotations

import logging
import math
import re
import time
from dataclasses import dataclass

from .errors import DeviceError, LimitError, ProtocolError
from .transport import Port, ask_again

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TERMINATOR = b"\r"
BAUDRATE = 9600  # 8N1, no handshake: open_port's defaults (§4.1)

# Upper bounds of the presets this driver will send; the lantz driver's limits for its lamp
# (max_lamp_amps = 12 A, max_lamp_power = 100 W). Configure them for the lamp actually fitted.
DEFAULT_MAX_CURRENT_A = 12.0
DEFAULT_MAX_POWER_W = 100

# STB bits (§4.1)
STB_LAMP_ON = 0x80
STB_EXTERNAL = 0x40
STB_POWER_MODE = 0x20
STB_CAL_MODE = 0x10
STB_FAULT = 0x08
STB_COMM = 0x04
STB_LIMIT = 0x02
STB_INTERLOCK = 0x01

# ESR bits (§4.1, IEEE-488.2 layout)
ESR_POWER_ON = 0x80
ESR_USER_REQUEST = 0x40
ESR_COMMAND_ERROR = 0x20
ESR_EXECUTION_ERROR = 0x10
ESR_DEVICE_ERROR = 0x08
ESR_QUERY_ERROR = 0x04
ESR_REQUEST_CONTROL = 0x02
ESR_OPERATION_COMPLETE = 0x01
ESR_ERROR_MASK = ESR_COMMAND_ERROR | ESR_EXECUTION_ERROR | ESR_DEVICE_ERROR | ESR_QUERY_ERROR

_REGISTER = re.compile(rb"^(STB|ESR)([0-9A-Fa-f]{2})$")
_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)$")


@dataclass(frozen=True)
class StatusByte:
    """The 69907 status byte (``STB?``), decoded with bit masks (anchors-protocols §4.1).

    Attributes
    ----------
    value : int
        Raw register, 0–255.
    lamp_on, external, power_mode, cal_mode, fault, comm, limit : bool
        Bits 7, 6, 5, 4, 3, 2, 1.
    interlock_open : bool
        The interlock is open (unsafe), from bit 0 and the configured polarity.
    """

    value: int
    lamp_on: bool
    external: bool
    power_mode: bool
    cal_mode: bool
    fault: bool
    comm: bool
    limit: bool
    interlock_open: bool

    @classmethod
    def decode(cls, value: int, *, interlock_bit_set_means_closed: bool = True) -> StatusByte:
        """Decode a raw STB value; see the module docstring for the polarity of bit 0."""
        bit0 = bool(value & STB_INTERLOCK)
        return cls(value=value, lamp_on=bool(value & STB_LAMP_ON), external=bool(value & STB_EXTERNAL),
                   power_mode=bool(value & STB_POWER_MODE), cal_mode=bool(value & STB_CAL_MODE),
                   fault=bool(value & STB_FAULT), comm=bool(value & STB_COMM), limit=bool(value & STB_LIMIT),
                   interlock_open=(not bit0) if interlock_bit_set_means_closed else bit0)


@dataclass(frozen=True)
class EventStatus:
    """The 69907 event status register (``ESR?`` and the reply to every set), decoded with bit masks.

    Attributes
    ----------
    value : int
        Raw register, 0–255.
    power_on, user_request, command_error, execution_error, device_error, query_error, request_control,
    operation_complete : bool
        Bits 7 … 0 (anchors-protocols §4.1).
    """

    value: int
    power_on: bool
    user_request: bool
    command_error: bool
    execution_error: bool
    device_error: bool
    query_error: bool
    request_control: bool
    operation_complete: bool

    @classmethod
    def decode(cls, value: int) -> EventStatus:
        return cls(value=value, power_on=bool(value & ESR_POWER_ON), user_request=bool(value & ESR_USER_REQUEST),
                   command_error=bool(value & ESR_COMMAND_ERROR),
                   execution_error=bool(value & ESR_EXECUTION_ERROR), device_error=bool(value & ESR_DEVICE_ERROR),
                   query_error=bool(value & ESR_QUERY_ERROR), request_control=bool(value & ESR_REQUEST_CONTROL),
                   operation_complete=bool(value & ESR_OPERATION_COMPLETE))

    @property
    def error(self) -> bool:
        """Any of the command, execution, device-dependent or query error bits."""
        return bool(self.value & ESR_ERROR_MASK)

    def describe(self) -> str:
        names = [name for name, flag in (("command error", self.command_error),
                                         ("execution error", self.execution_error),
                                         ("device-dependent error", self.device_error),
                                         ("query error", self.query_error)) if flag]
        return ", ".join(names) or "no error"


class Oriel69907Error(DeviceError):
    """The supply flagged an error in its event status register after a command.

    Attributes
    ----------
    esr : int
        The raw event status register.
    status : EventStatus
        The same, decoded.
    command : str
        The command that was refused.
    """

    def __init__(self, device: str, command: str, esr: int, *, received: bytes = b""):
        self.esr = esr
        self.status = EventStatus.decode(esr)
        self.command = command
        super().__init__(device, f"{command!r} refused: ESR {esr:02X} ({self.status.describe()})", received=received)


class Oriel69907:
    """Newport/Oriel 69907 arc-lamp power supply (anchors-protocols §4.1).

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=9600)`` (8N1 is the default framing).
    max_current_a : float
        Highest current preset this driver sends [A]; larger requests raise
        :class:`~drivers.errors.LimitError` before anything is sent.
    max_power_w : int
        Highest power preset this driver sends [W].
    interlock_bit_set_means_closed : bool
        Polarity of STB bit 0 (UNCONFIRMED, see the module docstring).
    retries : int
        How many times a *query* is asked again after a garbled or cut reply.
    clock : callable
        Time source [s] for :attr:`started_at_s` (``time.monotonic``; a simulated bench passes its
        ``SimClock.now`` so warm-up is measured in simulated time).
    name : str, optional
        Name used in errors; default the port's name.

    Attributes
    ----------
    started_at_s : float or None
        `clock` time of the last ``START`` this driver sent, None after ``STOP`` [s]. The arc-lamp sources
        measure the warm-up from it: the 69907 reports "lamp on" but not how warm the lamp is.
    """

    def __init__(self, port: Port, *, max_current_a: float = DEFAULT_MAX_CURRENT_A,
                 max_power_w: int = DEFAULT_MAX_POWER_W, interlock_bit_set_means_closed: bool = True,
                 retries: int = 1, clock=time.monotonic, name: str | None = None):
        self.port = port
        self.name = name or port.name
        self.max_current_a = float(max_current_a)
        self.max_power_w = int(max_power_w)
        self.interlock_bit_set_means_closed = interlock_bit_set_means_closed
        self.retries = int(retries)
        self.clock = clock
        self.started_at_s: float | None = None

    # -- exchanges ------------------------------------------------------------------------------------
    def _exchange(self, command: str) -> bytes:
        """Send one command, return its reply line without the CR."""
        reply = self.port.query(command.encode("ascii") + TERMINATOR, TERMINATOR)
        return reply[: -len(TERMINATOR)]

    def _ask(self, command: str, parse, *, retry: bool = True):
        """Query and parse, asking again (``retries`` times) after a garbled or cut reply when `retry`."""
        return ask_again(self.name, lambda: parse(command, self._exchange(command)), self.retries if retry else 0)

    def _register(self, command: str, body: bytes, name: str) -> int:
        match = _REGISTER.match(body)
        if not match:
            raise ProtocolError(self.name, f"{command!r}: expected {name}xx", received=body)
        if match.group(1).decode() != name:
            if match.group(1) == b"ESR":  # the supply answered a query with its error register
                raise Oriel69907Error(self.name, command, int(match.group(2), 16), received=body)
            raise ProtocolError(self.name, f"{command!r}: expected {name}xx", received=body)
        return int(match.group(2), 16)

    def _number(self, command: str, body: bytes) -> float:
        text = body.decode("ascii", errors="replace").strip()
        if _NUMBER.match(text):
            return float(text)
        match = _REGISTER.match(body)
        if match and match.group(1) == b"ESR":  # the supply answered the query with its error register
            raise Oriel69907Error(self.name, command, int(match.group(2), 16), received=body)
        raise ProtocolError(self.name, f"{command!r}: expected a number", received=body)

    def _command(self, command: str) -> EventStatus:
        """Send a set or action and check the ESR it answers with; never re-sent."""
        body = self._exchange(command)
        esr = EventStatus.decode(self._register(command, body, "ESR"))
        if esr.error:
            raise Oriel69907Error(self.name, command, esr.value, received=body)
        return esr

    # -- identity and state ---------------------------------------------------------------------------
    def identify(self) -> str:
        """Get the identification the supply reports (``IDN?``; RTS2 reads it as a number).

        Its format is not documented, so only empty, unprintable or register-shaped replies can be
        recognised as wrong.
        """
        def parse(command, body):
            text = body.decode("ascii", errors="replace").strip()
            match = _REGISTER.match(body)
            if match and match.group(1) == b"ESR":
                raise Oriel69907Error(self.name, command, int(match.group(2), 16), received=body)
            if not text or not text.isprintable() or match:
                raise ProtocolError(self.name, f"{command!r}: not an identification", received=body)
            return text
        return self._ask("IDN?", parse)

    def status_byte(self) -> StatusByte:
        """Get the status byte (``STB?`` → ``STBxx``): lamp on, fault, limit, interlock …

        Also keeps :attr:`started_at_s` true to the supply: cleared when the lamp is off (it went out, or was
        stopped at the front panel), and set to now when the lamp is found on without this driver having
        started it (the conservative guess: a full warm-up from now).
        """
        def parse(command, body):
            return StatusByte.decode(self._register(command, body, "STB"),
                                     interlock_bit_set_means_closed=self.interlock_bit_set_means_closed)
        stb = self._ask("STB?", parse)
        if not stb.lamp_on:
            self.started_at_s = None
        elif self.started_at_s is None:
            self.started_at_s = self.clock()
        return stb

    def event_status(self) -> EventStatus:
        """Get (and, IEEE-488.2 style, clear) the event status register (``ESR?`` → ``ESRxx``).

        Not asked again after a bad reply: the first read has cleared the register, a second would say 0.
        """
        return self._ask("ESR?", lambda command, body: EventStatus.decode(self._register(command, body, "ESR")),
                         retry=False)

    # -- lamp -----------------------------------------------------------------------------------------
    def start(self) -> None:
        """Strike the lamp (``START``) and note the time on the driver's clock.

        A START sent to a lamp this driver already started keeps the first time: the arc is not re-struck.
        """
        self._command("START")
        if self.started_at_s is None:
            self.started_at_s = self.clock()

    def stop(self) -> None:
        """Turn the lamp off (``STOP``)."""
        self._command("STOP")
        self.started_at_s = None

    # -- measurements (front-panel readings) ----------------------------------------------------------
    def amps(self) -> float:
        """Measure the output current [A] (``AMPS?``)."""
        return self._ask("AMPS?", self._number)

    def volts(self) -> float:
        """Measure the output voltage [V] (``VOLTS?``)."""
        return self._ask("VOLTS?", self._number)

    def watts(self) -> float:
        """Measure the output power [W] (``WATTS?``)."""
        return self._ask("WATTS?", self._number)

    def lamp_hours(self) -> float:
        """Get the hours run by the lamp fitted [h] (``LAMP HRS?``)."""
        return self._ask("LAMP HRS?", self._number)

    # -- presets --------------------------------------------------------------------------------------
    def current_preset_a(self) -> float:
        """Get the current preset [A] (``A-PRESET?``)."""
        return self._ask("A-PRESET?", self._number)

    def set_current_preset_a(self, current_a: float) -> None:
        """Set the current preset [A] (``A-PRESET=5.5``, one decimal), checked against `max_current_a` first."""
        current_a = float(current_a)
        if not (math.isfinite(current_a) and 0.0 <= current_a <= self.max_current_a):
            raise LimitError(self.name, f"current preset {current_a} A is outside [0, {self.max_current_a}] A")
        self._command(f"A-PRESET={current_a:.1f}")

    def power_preset_w(self) -> float:
        """Get the power preset [W] (``P-PRESET?``)."""
        return self._ask("P-PRESET?", self._number)

    def set_power_preset_w(self, power_w: int) -> None:
        """Set the power preset [W] (``P-PRESET=0095``, four digits), checked against `max_power_w` first."""
        self._command(f"P-PRESET={self._check_watts('power preset', power_w):04d}")

    # -- limits ---------------------------------------------------------------------------------------
    def current_limit_a(self) -> float:
        """Get the current limit [A] (``A-LIM?``)."""
        return self._ask("A-LIM?", self._number)

    def set_current_limit_a(self, current_a: float) -> None:
        """Set the current limit [A] (``A-LIM=12.0``, one decimal), checked against `max_current_a` first: the
        driver never lets the supply drive more than it would preset."""
        current_a = float(current_a)
        if not (math.isfinite(current_a) and 0.0 <= current_a <= self.max_current_a):
            raise LimitError(self.name, f"current limit {current_a} A is outside [0, {self.max_current_a}] A")
        self._command(f"A-LIM={current_a:.1f}")

    def power_limit_w(self) -> float:
        """Get the power limit [W] (``P-LIM?``)."""
        return self._ask("P-LIM?", self._number)

    def set_power_limit_w(self, power_w: int) -> None:
        """Set the power limit [W] (``P-LIM=0100``, four digits), checked against `max_power_w` first."""
        self._command(f"P-LIM={self._check_watts('power limit', power_w):04d}")

    def reset(self) -> None:
        """Restore the supply's factory presets and limits (``RST``); the driver's own limits still apply."""
        self._command("RST")

    def _check_watts(self, what: str, power_w) -> int:
        whole = isinstance(power_w, (int, float)) and not isinstance(power_w, bool) and float(power_w).is_integer()
        if not (whole and 0 <= power_w <= self.max_power_w):
            raise LimitError(self.name, f"{what} {power_w!r} W is not a whole number in [0, {self.max_power_w}] W")
        return int(power_w)
