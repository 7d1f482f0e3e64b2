"""Newport SMC100 single-axis controller (ASCII protocol) with a rotation stage (anchors-protocols §3.1).

Protocol decisions (anchors-protocols §3.1):

* Line: 57600 baud, 8N1, XON/XOFF. Commands are ``<address><CC><value>\\r\\n``; replies echo the address
  and the command, then the value: ``1TP12.5\\r\\n``.
* ``TP``, ``TS`` and ``TE`` are sent without ``?`` (QMI and pymeasure); ``ID?``, ``VA?`` and ``AC?`` with it.
* Every command that has no reply (``OR``, ``PA``, ``ST``, ``VA``, ``AC``) is followed by ``TE``, and a letter
  other than ``@`` becomes a typed error carrying the letter and its meaning (pymeasure's table).
* :meth:`Smc100Axis.expected_motion` is the velocity and acceleration the controller holds (``VA?``,
  ``AC?``), in the stage's preset units (degrees for a rotation stage).
* Controller states are decoded by ranges, because the public tables disagree on single codes:
  0A–11 NOT REFERENCED, 14 CONFIGURATION, 1E–1F HOMING, 28 MOVING, 32–38 READY, 3C–3F DISABLE,
  46–47 JOGGING. Positioner error bits come from pystages' table.
* ``OR`` is only accepted in NOT REFERENCED; homing a referenced controller (READY or DISABLE) therefore
  resets it first with ``RS`` (pymeasure waits 1 s after it).
* A reply that is cut short or corrupted (no terminator, wrong echo, a value that does not parse) raises
  :class:`ProtocolError`; read-only queries are asked once more from a clean buffer, ``TE`` never is, since
  reading it may clear the error (UNCONFIRMED).
* Reply numbers are parsed with ``float()`` since their format is UNCONFIRMED; numbers are sent with up
  to 6 decimals, trailing zeros removed (``PA12.5``).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

from .errors import DeviceFault, DeviceTimeout, LimitError, ProtocolError
from .interfaces import AxisMotion, Limits, RotaryAxis
from .transport import Port, ask_again, open_port

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TERMINATOR = b"\r\n"

NOT_REFERENCED = "NOT REFERENCED"
CONFIGURATION = "CONFIGURATION"
HOMING = "HOMING"
MOVING = "MOVING"
READY = "READY"
DISABLE = "DISABLE"
JOGGING = "JOGGING"

#: Controller state ranges of the ``ef`` part of TS (anchors-protocols §3.1, decoded by ranges).
STATE_RANGES: tuple[tuple[int, int, str], ...] = (
    (0x0A, 0x11, NOT_REFERENCED),
    (0x14, 0x14, CONFIGURATION),
    (0x1E, 0x1F, HOMING),
    (0x28, 0x28, MOVING),
    (0x32, 0x38, READY),
    (0x3C, 0x3F, DISABLE),
    (0x46, 0x47, JOGGING),
)

#: Positioner error bits of the ``abcd`` part of TS (anchors-protocols §3.1, pystages ``Error``).
POSITIONER_ERRORS: dict[int, str] = {
    0: "negative end of run",
    1: "positive end of run",
    2: "peak current limit",
    3: "RMS current limit",
    4: "short circuit",
    5: "following error",
    6: "homing time-out",
    7: "wrong ESP stage",
    8: "DC voltage too low",
    9: "80 W output power exceeded",
}
END_OF_RUN_MASK = 0b11

#: Command error letters of TE (anchors-protocols §3.1, pymeasure ``CommandError.MESSAGES``).
COMMAND_ERRORS: dict[str, str] = {
    "@": "no error",
    "A": "unknown message code or floating point controller address",
    "B": "controller address not correct",
    "C": "parameter missing or out of specified range",
    "D": "command not allowed",
    "E": "home sequence already started",
    "F": "ESP stage name unknown",
    "G": "displacement out of limits",
    "H": "command not allowed in NOT REFERENCED state",
    "I": "command not allowed in CONFIGURATION state",
    "J": "command not allowed in DISABLE state",
    "K": "command not allowed in READY state",
    "L": "command not allowed in HOMING state",
    "M": "command not allowed in MOVING state",
    "N": "current position out of software limit",
    "S": "communication time-out",
    "U": "error during EEPROM access",
    "V": "error during command execution",
    "W": "command not allowed for PP version",
    "X": "command not allowed for CC version",
}
_PROTOCOL_LETTERS = frozenset("ABS")  # the controller did not understand us: a protocol problem


class Smc100CommandError(DeviceFault):
    """The controller refused a command: TE reported `code` (a letter) meaning `meaning`."""

    def __init__(self, device: str, code: str, meaning: str, command: str = ""):
        self.code, self.meaning = code, meaning
        after = f" after {command!r}" if command else ""
        super().__init__(device, f"command error {code!r}{after}: {meaning}")


def state_name(code: int) -> str | None:
    """Controller state of a TS state code, by range; None if unknown (anchors-protocols §3.1)."""
    for low, high, name in STATE_RANGES:
        if low <= code <= high:
            return name
    return None


def positioner_errors(mask: int) -> list[str]:
    """Meanings of the positioner error bits set in `mask`."""
    return [text for bit, text in POSITIONER_ERRORS.items() if mask >> bit & 1]


def format_number(value: float) -> str:
    """A number as the SMC100 takes it: up to 6 decimals, no trailing zeros, no exponent (``12.5``, ``90``)."""
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


@dataclass(frozen=True)
class Smc100Status:
    """Decoded TS reply.

    Attributes
    ----------
    error_bits : int
        Positioner error mask (16 bits).
    state_code : int
        Controller state code (hex ``ef`` of TS).
    state : str
        One of NOT REFERENCED, CONFIGURATION, HOMING, MOVING, READY, DISABLE, JOGGING.
    """

    error_bits: int
    state_code: int
    state: str

    @property
    def errors(self) -> list[str]:
        return positioner_errors(self.error_bits)


def parse_status(device: str, value: str) -> Smc100Status:
    """Decode the value of a TS reply, ``abcdef`` (4 hex digits of error bits, 2 of state)."""
    if len(value) != 6:
        raise ProtocolError(device, f"TS value {value!r} is not 6 hex digits", received=value.encode())
    try:
        error_bits, code = int(value[:4], 16), int(value[4:], 16)
    except ValueError:
        raise ProtocolError(device, f"TS value {value!r} is not hexadecimal", received=value.encode()) from None
    state = state_name(code)
    if state is None:
        raise ProtocolError(device, f"unknown controller state 0x{code:02X}", received=value.encode())
    return Smc100Status(error_bits, code, state)


class Smc100Axis(RotaryAxis):
    """One rotation axis on a Newport SMC100 controller (anchors-protocols §3.1).

    The constructor does no I/O.

    Parameters
    ----------
    port : Port
        Open port (57600 baud, XON/XOFF; see :meth:`open`).
    address : int
        Controller address (1 on RS-232; 1–31 when chained on RS-485).
    name : str, optional
        Name in errors; default the port's name.
    limits : Limits
        Soft limits of the bench [°], checked before anything is sent.
    reset_wait_s : float
        Wait after ``RS`` before the controller answers again [s] (pymeasure: 1 s).
    retries : int
        How many times a read-only query is repeated after a corrupted or truncated reply.
    """

    def __init__(self, port: Port, *, address: int = 1, name: str | None = None,
                 limits: Limits = Limits(-360.0, 360.0), reset_wait_s: float = 1.0, retries: int = 1):
        if not 0 <= address <= 31:
            raise ValueError(f"SMC100 addresses are 0–31, got {address}")
        self.port = port
        self.address = address
        self.name = name or port.name
        self.limits = limits
        self.reset_wait_s = reset_wait_s
        self.retries = retries

    @classmethod
    def open(cls, url: str, *, timeout_s: float = 1.0, record=None, **kwargs) -> Smc100Axis:
        """Open the port at `url` with the SMC100 line settings (57600 baud, 8N1, XON/XOFF)."""
        port = open_port(url, baudrate=57600, xonxoff=True, timeout_s=timeout_s, record=record,
                         name=kwargs.get("name"))
        return cls(port, **kwargs)

    # -- exchanges --------------------------------------------------------------------------------------
    def _frame(self, command: str, value: str = "") -> bytes:
        return f"{self.address}{command}{value}".encode("ascii") + TERMINATOR

    def _ask_once(self, command: str) -> str:
        echo = f"{self.address}{command.rstrip('?')}"
        try:
            reply = self.port.query(self._frame(command), TERMINATOR)
        except DeviceTimeout as exc:
            if exc.received:  # a line began but never ended: cut or corrupted on the way
                raise ProtocolError(self.name, f"no complete reply to {command!r}", received=exc.received) from None
            raise
        text = reply[: -len(TERMINATOR)].decode("ascii", "replace")
        if not text.startswith(echo):
            raise ProtocolError(self.name, f"reply to {command!r} does not start with {echo!r}", received=reply)
        return text[len(echo):].strip()

    def _ask(self, command: str, parse=str, *, retry: bool = True):
        """Query `command` and return ``parse(value)``; a corrupted reply is asked again if `retry`."""
        def attempt():
            value = self._ask_once(command)
            try:
                return parse(value)
            except ValueError:
                raise ProtocolError(self.name, f"cannot parse {value!r} as the value of {command!r}",
                                    received=value.encode()) from None

        return ask_again(self.name, attempt, self.retries if retry else 0, on=ProtocolError)

    def last_error(self) -> str:
        """Letter of the last command error (TE); ``"@"`` is none."""
        letter = self._ask("TE", retry=False)
        if len(letter) != 1 or letter not in COMMAND_ERRORS:
            raise ProtocolError(self.name, f"unknown command error code {letter!r}", received=letter.encode())
        return letter

    def _command(self, command: str, value: str = "") -> None:
        """Send a command without reply, then check TE."""
        with self.port.transaction():
            self.port.discard_input()
            self.port.write(self._frame(command, value))
            letter = self.last_error()
        if letter != "@":
            meaning = COMMAND_ERRORS[letter]
            sent = f"{self.address}{command}{value}"
            if letter in _PROTOCOL_LETTERS:
                raise ProtocolError(self.name, f"command error {letter!r} after {sent!r}: {meaning}")
            raise Smc100CommandError(self.name, letter, meaning, sent)

    # -- identity ---------------------------------------------------------------------------------------
    def identify(self) -> str:
        """Controller revision (VE) and stage identifier (ID?)."""
        return f"{self._ask('VE')}; stage {self._ask('ID?')}"

    # -- state ------------------------------------------------------------------------------------------
    def status(self) -> Smc100Status:
        """Positioner errors and controller state (TS)."""
        return parse_status(self.name, self._ask("TS"))

    def state(self) -> str:
        """Controller state name (TS)."""
        return self.status().state

    def position_deg(self) -> float:
        """Measured position [°] (TP)."""
        value = self._ask("TP", float)
        if not math.isfinite(value):
            raise ProtocolError(self.name, f"position {value} is not finite")
        return value

    def is_moving(self) -> bool:
        """True while MOVING, HOMING or JOGGING.

        Raises
        ------
        DeviceFault
            A positioner error bit is set (end of run = limit switch, following error …); end-of-run bits
            are tolerated while homing, which may seek a switch.
        """
        status = self.status()
        errors = status.error_bits & ~(END_OF_RUN_MASK if status.state == HOMING else 0)
        if errors:
            raise DeviceFault(self.name, f"positioner error: {', '.join(positioner_errors(errors))} "
                                         f"(state {status.state}, 0x{status.state_code:02X})")
        return status.state in (MOVING, HOMING, JOGGING)

    # -- motion -----------------------------------------------------------------------------------------
    def _start_move(self, angle_deg: float) -> None:
        self._command("PA", format_number(angle_deg))

    def stop(self) -> None:
        """Stop motion (ST)."""
        self._command("ST")

    def reset(self) -> None:
        """Reset the controller (RS) → NOT REFERENCED; waits `reset_wait_s`."""
        with self.port.transaction():
            self.port.discard_input()
            self.port.write(self._frame("RS"))
        time.sleep(self.reset_wait_s)

    def home(self, *, wait: bool = True, timeout_s: float = 300.0) -> None:
        """Home search (OR), which the controller accepts only in NOT REFERENCED.

        From READY or DISABLE the controller is reset (RS) first; in any other state (moving, homing,
        configuration, jogging) homing is refused.

        Raises
        ------
        DeviceFault
            Refused in the present state, or homing ended elsewhere than READY.
        """
        state = self.state()
        if state in (READY, DISABLE):
            self.reset()
            state = self.state()
        if state != NOT_REFERENCED:
            raise DeviceFault(self.name, f"cannot home in state {state}")
        self._command("OR")
        if wait:
            self.wait_until_stopped(timeout_s=timeout_s)
            state = self.state()
            if state != READY:
                raise DeviceFault(self.name, f"homing ended in state {state}")

    # -- velocity ---------------------------------------------------------------------------------------
    def velocity_deg_s(self) -> float:
        """Move velocity [°/s] (VA?)."""
        return self._ask("VA?", float)

    def acceleration_deg_s2(self) -> float:
        """Move acceleration [°/s²] (AC?)."""
        return self._ask("AC?", float)

    def expected_motion(self) -> AxisMotion:
        """The move velocity and acceleration the controller holds (VA?, AC?)."""
        return AxisMotion(self.velocity_deg_s(), self.acceleration_deg_s2())

    def set_velocity_deg_s(self, velocity_deg_s: float) -> None:
        """Set the move velocity [°/s] (VA); the controller checks the range (TE 'C')."""
        if not (velocity_deg_s > 0 and math.isfinite(velocity_deg_s)):
            raise LimitError(self.name, f"velocity must be positive and finite, got {velocity_deg_s}")
        self._command("VA", format_number(velocity_deg_s))

    def set_acceleration_deg_s2(self, accel_deg_s2: float) -> None:
        """Set the move acceleration [°/s²] (AC); the controller checks the range (TE 'C')."""
        if not (accel_deg_s2 > 0 and math.isfinite(accel_deg_s2)):
            raise LimitError(self.name, f"acceleration must be positive and finite, got {accel_deg_s2}")
        self._command("AC", format_number(accel_deg_s2))

    def close(self) -> None:
        self.port.close()
