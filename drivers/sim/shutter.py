"""Protocol front of the simulated Thorlabs SC10 shutter controller in front of the arc lamp.

Device analysis (sources and UNCONFIRMED points in :mod:`drivers.shutter`):

* Lines end with CR. The controller echoes each command and a CR, then — for a query — the value and a
  CR, then the prompt ``"> "``. Commands are lower case.
* The keyword table of the SC10 manual (8654-D02, "Keywords (Commands and Queries)"):

  ===========================  ===================================================================
  ``?``                        the list of commands (one line here; its real layout is UNCONFIRMED)
  ``id?``                      model and firmware (also ``*idn?``, which Micro-Manager sends)
  ``ens`` / ``ens?``           toggle the enable / 1 enabled, 0 disabled
  ``rep=n`` / ``rep?``         repeat count of repeat mode, 1 … 99
  ``mode=n`` / ``mode?``       1 manual, 2 auto, 3 single, 4 repeat, 5 external gate
  ``trig=n`` / ``trig?``       0 internal trigger, 1 external trigger
  ``xto=n`` / ``xto?``         trigger out follows 0 the shutter, 1 the controller
  ``open=n`` / ``open?``       open time [ms], at most 6 digits
  ``shut=n`` / ``shut?``       shut time [ms], at most 6 digits
  ``closed?``                  1 closed, 0 open
  ``interlock?``               1 tripped
  ``baud=n`` / ``baud?``       0 9600, 1 115200 baud (stored; a TCP or pty link has no baud rate)
  ``save``                     store the mode information: trigger-out mode and baud rate
  ``savp``                     store the configuration: mode, repeat count, trigger, open and shut times
  ``resp``                     load the stored configuration
  ===========================  ===================================================================

  ``default`` (factory settings) is not in that table; InstrumentKit sends it, so it is accepted
  (UNCONFIRMED). The factory settings here (:data:`FACTORY`: manual mode, 100 ms open and shut, one
  repeat, internal trigger) are placeholders, UNCONFIRMED. Sets and actions answer the echo and the prompt.
* The modes. Enabled in manual mode, the shutter is open. Auto mode opens it for the open time and shuts it
  for the shut time, over and over, while enabled; single mode opens it once; repeat mode runs `rep`
  open/shut cycles; external-gate mode follows the gate input (back door :meth:`set_gate`). With the
  internal trigger the ``ens`` that enables starts the sequence, and a single or repeat sequence disables
  the controller when it ends (the enable is the start button; UNCONFIRMED); with the external trigger
  ``ens`` arms the controller and each pulse (back door :meth:`external_trigger`) starts a sequence. A new
  ``mode=`` or ``trig=`` disables the controller (the shutter closes; UNCONFIRMED, the safe reading). The
  timed state is brought up to date whenever the controller handles a command or is polled (every few
  milliseconds over TCP or a pty, before every read on a ``sim://`` port); the world's shutter follows it.
  In instant mode (clock time scale 0) simulated time stands still, so a sequence stays where it is.
* A bad keyword answers ``Command error CMD_NOT_DEFINED``, a bad argument ``Command error CMD_ARG_INVALID``
  (the texts of sibling Thorlabs controllers; UNCONFIRMED for the SC10) — in place of the value line.
* Tripping the interlock (back door :meth:`trip_interlock`) disables the controller and closes the
  shutter; ``ens`` is then ignored (answered with the echo and the prompt only) until
  :meth:`reset_interlock`.

Where InstrumentKit (0.6.0) and the manual disagree, the manual's behaviour is the default and the client's
an option (research note peer-clients.md):

* ``ens=1`` / ``ens=0``: InstrumentKit's ``enable`` setter sends them; the manual has only the toggle, so
  they are ``CMD_NOT_DEFINED`` unless the simulator is built with ``accept_ens_value=True``.
* InstrumentKit's ``save()``, ``save_mode()``, ``restore()`` and ``default()`` *query* ``savp``, ``save``,
  ``resp`` and ``default`` and so wait for a value line the manual does not document (other public clients
  send them as commands). ``action_reply="1"`` makes them answer that line.

Back door: the WireFaults of every simulator, :meth:`trip_interlock`, :meth:`reset_interlock`,
:meth:`external_trigger`, :meth:`set_gate`.
"""

from __future__ import annotations

from .device import LineDevice
from .world import SimWorld

IDENTITY = "THORLABS SC10 (simulated) VERSION 1.0"
PROMPT = "> "
NOT_DEFINED = "Command error CMD_NOT_DEFINED"
ARG_INVALID = "Command error CMD_ARG_INVALID"

MANUAL, AUTO, SINGLE, REPEAT, GATE = 1, 2, 3, 4, 5
# The settings `default` restores and the controller starts with (placeholders, see the module docstring).
FACTORY = {"mode": MANUAL, "rep": 1, "trig": 0, "xto": 0, "open": 100, "shut": 100, "baud": 0}
_CONFIGURATION = ("mode", "rep", "trig", "open", "shut")  # what savp stores and resp loads
_MODE_INFORMATION = ("xto", "baud")  # what save stores
_RANGES = {"mode": range(1, 6), "rep": range(1, 100), "trig": range(0, 2), "xto": range(0, 2),
           "open": range(0, 1_000_000), "shut": range(0, 1_000_000), "baud": range(0, 2)}
_COMMANDS = ("? id? ens ens? rep=n rep? mode=n mode? trig=n trig? xto=n xto? open=n open? shut=n shut? "
             "closed? interlock? baud=n baud? save savp resp")


class ThorlabsSC10Simulator(LineDevice):
    """The SC10 of the simulated xenon sun simulator; it drives ``world.lamp.shutter_open``.

    Parameters
    ----------
    world : SimWorld
    accept_ens_value : bool
        Accept InstrumentKit's ``ens=1`` / ``ens=0`` (not in the manual).
    action_reply : str, optional
        A value line for ``savp``, ``save``, ``resp`` and ``default`` (InstrumentKit reads one); None answers
        the echo and the prompt only.
    """

    name = "sc10"
    in_terminator = b"\r"

    def __init__(self, world: SimWorld, *, accept_ens_value: bool = False, action_reply: str | None = None):
        super().__init__()
        self.world = world
        self.accept_ens_value = accept_ens_value
        self.action_reply = action_reply
        self.settings = dict(FACTORY)
        self.stored = dict(FACTORY)  # the controller's EEPROM
        self.enabled = False
        self.interlock = False
        self.gate = False  # the external gate input (mode 5)
        self.sequence_start: float | None = None  # clock time the running open/shut sequence started [s]
        self.commands = 0
        self._apply()

    @property
    def mode(self) -> int:
        """The operating mode (1 manual … 5 external gate)."""
        return self.settings["mode"]

    # -- timing ----------------------------------------------------------------------------------------
    def _cycles(self) -> int | None:
        """Open/shut cycles of one sequence in the current mode; None for endless (auto)."""
        return {AUTO: None, SINGLE: 1, REPEAT: self.settings["rep"]}[self.settings["mode"]]

    def _start_sequence(self) -> None:
        self.sequence_start = self.world.clock.now()

    def _is_open(self) -> bool:
        """Whether the shutter is open now; ends a finished sequence on the way."""
        if self.interlock or not self.enabled:
            return False
        mode = self.settings["mode"]
        if mode == MANUAL:
            return True
        if mode == GATE:
            return self.gate
        if self.sequence_start is None:
            return False  # armed, waiting for an external trigger
        open_s, shut_s = self.settings["open"] / 1000.0, self.settings["shut"] / 1000.0
        elapsed = self.world.clock.now() - self.sequence_start
        cycles = self._cycles()
        period = open_s + shut_s
        if cycles is not None and elapsed >= cycles * period:
            self.sequence_start = None  # the sequence is over
            if self.settings["trig"] == 0:
                self.enabled = False  # started by ens: the controller disables itself
            return False
        if period <= 0:
            return False
        return (elapsed % period) < open_s

    def _apply(self) -> None:
        self.world.lamp.shutter_open = self._is_open()

    def unsolicited(self) -> bytes:
        self._apply()  # a poll brings the timed state up to date; the SC10 volunteers nothing
        return b""

    # -- back door -------------------------------------------------------------------------------------
    def trip_interlock(self) -> None:
        """The interlock opens: the controller disables itself and the shutter closes."""
        self.interlock = True
        self.enabled = False
        self.sequence_start = None
        self._apply()

    def reset_interlock(self) -> None:
        self.interlock = False
        self._apply()

    def external_trigger(self) -> None:
        """A pulse on the trigger input: starts a sequence when enabled with ``trig=1`` in mode 2, 3 or 4."""
        self._apply()
        if self.enabled and self.settings["trig"] == 1 and self.settings["mode"] in (AUTO, SINGLE, REPEAT):
            self._start_sequence()
        self._apply()

    def set_gate(self, high: bool) -> None:
        """The level of the external gate input (followed in mode 5)."""
        self.gate = bool(high)
        self._apply()

    # -- protocol --------------------------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes:
        self.commands += 1
        command = line.decode("ascii", errors="replace").strip()
        self._apply()
        value = self._dispatch(command)
        self._apply()
        body = f"{command}\r" + (f"{value}\r" if value is not None else "") + PROMPT
        return body.encode("ascii")

    def _toggle(self) -> None:
        if self.interlock:
            return  # ignored while the interlock is tripped
        self.enabled = not self.enabled
        self.sequence_start = None
        if self.enabled and self.settings["trig"] == 0 and self.settings["mode"] in (AUTO, SINGLE, REPEAT):
            self._start_sequence()

    def _dispatch(self, command: str) -> str | None:
        settings = self.settings
        queries = {
            "?": lambda: _COMMANDS,
            "id?": lambda: IDENTITY,
            "*idn?": lambda: IDENTITY,
            "ens?": lambda: "1" if self.enabled else "0",
            "closed?": lambda: "0" if self._is_open() else "1",
            "interlock?": lambda: "1" if self.interlock else "0",
        }
        if command in queries:
            return queries[command]()
        if command.endswith("?") and command[:-1] in settings:
            return str(settings[command[:-1]])
        if command == "ens":
            self._toggle()
            return None
        if command in ("savp", "save", "resp", "default"):
            keys = {"savp": _CONFIGURATION, "save": _MODE_INFORMATION, "resp": _CONFIGURATION,
                    "default": tuple(FACTORY)}[command]
            source, target = {"savp": (settings, self.stored), "save": (settings, self.stored),
                              "resp": (self.stored, settings), "default": (FACTORY, settings)}[command]
            for key in keys:
                target[key] = source[key]
            if command in ("resp", "default"):
                self.sequence_start = None
            return self.action_reply
        name, sep, value = command.partition("=")
        if sep and name == "ens" and self.accept_ens_value:
            if value not in ("0", "1"):
                return ARG_INVALID
            if (value == "1") != self.enabled:
                self._toggle()
            return None
        if sep and name in settings:
            if not (value.isdigit() and len(value) <= 6 and int(value) in _RANGES[name]):
                return ARG_INVALID
            settings[name] = int(value)
            if name in ("mode", "trig") and self.enabled:
                self.enabled = False  # a new mode or trigger source disables the controller
                self.sequence_start = None
            return None
        return NOT_DEFINED


ShutterSimulator = ThorlabsSC10Simulator  # the name drivers.sim.bench builds the xenon bench with
