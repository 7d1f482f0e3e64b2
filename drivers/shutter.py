"""Driver of the Thorlabs SC10 shutter controller (with an SH05/SH1 beam shutter) in front of the arc lamp.

The Oriel 69907 supply has no shutter command (anchors-protocols §4.1), so the xenon sun simulator needs a
separate shutter controller. The SC10 is chosen because its ASCII command set is documented in its manual
and used by three independent public drivers.

Protocol, and where each fact comes from (checked for this module; not in the research note):

=============================================  ===========================================================
fact                                           sources
=============================================  ===========================================================
9600 baud, 8N1, no handshake (factory          Micro-Manager ``ThorlabsSC10/SC10.cpp`` ("9600 baud, 8 data
setting; ``baud=1`` selects 115200)            bits, no parity, 1 stop bit, no flow control") and its
                                               device page; InstrumentKit ``thorlabs/sc10.py`` (``baud?``)
commands lower case, sent with a CR            SC10 manual keyword table ("All commands and queries are
                                               in lower case letters"); Micro-Manager sends ``cmd + "\\r"``;
                                               InstrumentKit terminator ``"\\r"``
the controller **echoes** the command, then    Micro-Manager ("the SC10 echoes the command", strips
CR, then the value and CR (queries only),      ``len(cmd) + 1`` characters); InstrumentKit tests:
then a **prompt** ``"> "``                     ``"ens?" → "ens?\\r0\\r> "``, ``"mode=2" → "mode=2\\r> "``;
                                               Micro-Manager reads each answer up to ``">"``
``id?`` → model and firmware                   manual table; InstrumentKit ``name``
``ens`` toggles the enable (in manual mode:    manual table ("Toggle enable"); Micro-Manager ``SetOpen``
the shutter opens/closes); ``ens?`` → 0/1      reads ``ens?`` and sends ``ens`` only when it must change
``closed?`` → "1" closed, "0" open             manual table; InstrumentKit ``closed``
``interlock?`` → "1" tripped                   manual table; InstrumentKit ``interlock``
``mode=n`` / ``mode?``, 1 manual … 5 gated     manual table; Micro-Manager sets ``mode=1`` at start-up
=============================================  ===========================================================

**UNCONFIRMED** (to settle with the hardware, as in anchors-protocols §7):

* The exact error text. The manual only says the unit "will return an error string" for a bad keyword or
  argument; sibling Thorlabs controllers (FW102C, MC2000B, LCC25) answer ``Command error CMD_NOT_DEFINED``
  or ``CMD_ARG_INVALID``. This driver raises :class:`SC10CommandError` on any answer containing "error".
* Whether the prompt always carries the trailing space (InstrumentKit ``"> "``; Micro-Manager only waits
  for ``">"``). This driver waits for ``"> "``.
* The format of the ``id?`` answer, and how the controller answers ``ens`` while its interlock is tripped.
  The driver never trusts the toggle: it reads ``closed?`` afterwards and, if the shutter did not move,
  reports the interlock state in a :class:`~drivers.errors.DeviceFault`.

Queries are retried once after a garbled or cut reply; ``ens`` is never re-sent blindly (a second toggle
would undo the first): after a bad reply to it the driver reads the state back and decides from that.
"""

from __future__ import annotations

import logging

from .errors import DeviceError, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from .transport import Port, ask_again

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TERMINATOR = b"\r"
PROMPT = b"> "
BAUDRATE = 9600  # 8N1, no handshake: open_port's defaults

MODES = {1: "manual", 2: "auto", 3: "single", 4: "repeat", 5: "external gate"}  # SC10 manual, mode=n


class SC10CommandError(DeviceError):
    """The SC10 answered a command with an error string (``Command error …``)."""


class ThorlabsSC10:
    """Thorlabs SC10 shutter controller (see the module docstring for the protocol and its sources).

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=9600)``.
    retries : int
        How many times a *query* is asked again after a garbled or cut reply.
    name : str, optional
        Name used in errors; default the port's name.
    """

    def __init__(self, port: Port, *, retries: int = 1, name: str | None = None):
        self.port = port
        self.name = name or port.name
        self.retries = int(retries)

    # -- exchanges ------------------------------------------------------------------------------------
    def _exchange(self, command: str) -> str | None:
        """Send `command`; return the value line of a query, None for a set. Checks the echo and the prompt."""
        sent = command.encode("ascii")
        reply = self.port.query(sent + TERMINATOR, PROMPT)
        lines = reply[: -len(PROMPT)].split(TERMINATOR)
        # a well-formed reply is: echo, CR, [value, CR,] prompt -> split gives [echo, (value,) b""]
        if len(lines) not in (2, 3) or lines[-1] != b"" or lines[0] != sent:
            raise ProtocolError(self.name, f"{command!r}: expected the echo, a value and the prompt", received=reply)
        if len(lines) == 2:
            return None
        value = lines[1].decode("ascii", errors="replace")
        if "error" in value.lower():
            raise SC10CommandError(self.name, f"{command!r}: {value.strip()}", received=reply)
        if not value.isprintable():
            raise ProtocolError(self.name, f"{command!r}: unprintable answer", received=reply)
        return value.strip()

    def _ask(self, command: str, parse):
        def attempt():
            value = self._exchange(command)
            if value is None:
                raise ProtocolError(self.name, f"{command!r}: no value in the reply")
            return parse(command, value)

        return ask_again(self.name, attempt, self.retries)
    def _set(self, command: str) -> None:
        if self._exchange(command) is not None:
            raise ProtocolError(self.name, f"{command!r}: unexpected value in the reply to a set")

    def _flag(self, command: str, value: str) -> bool:
        if value not in ("0", "1"):
            raise ProtocolError(self.name, f"{command!r}: expected 0 or 1, got {value!r}")
        return value == "1"

    def _int(self, command: str, value: str) -> int:
        if not value.isdigit():
            raise ProtocolError(self.name, f"{command!r}: expected an integer, got {value!r}")
        return int(value)

    # -- queries --------------------------------------------------------------------------------------
    def identify(self) -> str:
        """Get the model number and firmware revision (``id?``)."""
        return self._ask("id?", lambda command, value: value)

    def mode(self) -> int:
        """Get the operating mode (``mode?``): 1 manual, 2 auto, 3 single, 4 repeat, 5 external gate."""
        return self._ask("mode?", self._int)

    def enabled(self) -> bool:
        """Get the enable state (``ens?``); in manual mode, enabled means the shutter is driven open."""
        return self._ask("ens?", self._flag)

    def is_closed(self) -> bool:
        """Get whether the shutter is closed (``closed?`` → "1" closed, "0" open)."""
        return self._ask("closed?", self._flag)

    def is_open(self) -> bool:
        """Get whether the shutter is open (the negation of ``closed?``)."""
        return not self.is_closed()

    def interlock_tripped(self) -> bool:
        """Get whether the controller's interlock is tripped (``interlock?`` → "1" tripped)."""
        return self._ask("interlock?", self._flag)

    # -- commands -------------------------------------------------------------------------------------
    def set_mode(self, mode: int) -> None:
        """Set the operating mode (``mode=1`` manual …); checked before sending."""
        if isinstance(mode, bool) or mode not in MODES:
            raise LimitError(self.name, f"mode {mode!r} is not one of {sorted(MODES)}")
        self._set(f"mode={int(mode)}")

    def toggle_enable(self) -> None:
        """Toggle the enable (``ens``). Low level: :meth:`open` and :meth:`close` read the state first."""
        self._set("ens")

    def configure(self) -> None:
        """Put the controller in manual mode, as Micro-Manager does at start-up: ``ens`` then opens and closes."""
        if self.mode() != 1:
            self.set_mode(1)

    def open(self) -> None:
        """Open the shutter and check that it opened; a tripped interlock raises DeviceFault."""
        self._drive(open_=True)

    def close(self) -> None:
        """Close the shutter and check that it closed."""
        self._drive(open_=False)

    def _drive(self, *, open_: bool) -> None:
        if self.enabled() != open_:
            try:
                self.toggle_enable()
            except (ProtocolError, DeviceTimeout) as exc:
                # the toggle may or may not have happened: look, never toggle twice blindly
                if self.enabled() != open_:
                    raise
                log.warning("%s: bad reply to 'ens' (%s) but the shutter is where it should be", self.name, exc)
        if self.is_closed() == open_:
            word = "open" if open_ else "close"
            why = "the interlock is tripped" if self.interlock_tripped() else "it did not move"
            raise DeviceFault(self.name, f"shutter did not {word}: {why}")
