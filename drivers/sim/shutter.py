"""Protocol front of the simulated Thorlabs SC10 shutter controller in front of the arc lamp.

Device analysis (sources and UNCONFIRMED points in :mod:`drivers.shutter`):

* Lines end with CR. The controller echoes each command and a CR, then — for a query — the value and a
  CR, then the prompt ``"> "``. Commands are lower case.
* ``id?`` (and ``*idn?``, which Micro-Manager sends) → model and firmware; ``ens`` toggles the enable;
  ``ens?`` → 0/1; ``closed?`` → 1 closed, 0 open; ``interlock?`` → 1 tripped; ``mode=n`` (1–5) /
  ``mode?``.
* State: mode, enable, interlock. The shutter is open when the controller is enabled in manual mode
  (mode 1) and the interlock is closed; that drives ``world.lamp.shutter_open``. The timed modes (auto,
  single, repeat, gated) are accepted and stored but not timed: their shutter stays closed here.
* A bad keyword answers ``Command error CMD_NOT_DEFINED``, a bad argument ``Command error CMD_ARG_INVALID``
  (the texts of sibling Thorlabs controllers; UNCONFIRMED for the SC10).
* Tripping the interlock (back door :meth:`trip_interlock`) disables the controller and closes the
  shutter; ``ens`` is then ignored (answered with the echo and the prompt only) until
  :meth:`reset_interlock`.

Back door: the WireFaults of every simulator, :meth:`trip_interlock`, :meth:`reset_interlock`.
"""

from __future__ import annotations

from .device import LineDevice
from .world import SimWorld

IDENTITY = "THORLABS SC10 (simulated) VERSION 1.0"
PROMPT = "> "


class ThorlabsSC10Simulator(LineDevice):
    """The SC10 of the simulated xenon sun simulator; it drives ``world.lamp.shutter_open``."""

    name = "sc10"
    in_terminator = b"\r"

    def __init__(self, world: SimWorld):
        super().__init__()
        self.world = world
        self.mode = 1
        self.enabled = False
        self.interlock = False
        self.commands = 0
        self._apply()

    def _apply(self) -> None:
        self.world.lamp.shutter_open = self.enabled and self.mode == 1 and not self.interlock

    # -- back door -------------------------------------------------------------------------------------
    def trip_interlock(self) -> None:
        """The interlock opens: the controller disables itself and the shutter closes."""
        self.interlock = True
        self.enabled = False
        self._apply()

    def reset_interlock(self) -> None:
        self.interlock = False
        self._apply()

    # -- protocol --------------------------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes:
        self.commands += 1
        command = line.decode("ascii", errors="replace").strip()
        value = self._dispatch(command)
        body = f"{command}\r" + (f"{value}\r" if value is not None else "") + PROMPT
        return body.encode("ascii")

    def _dispatch(self, command: str) -> str | None:
        queries = {
            "id?": lambda: IDENTITY,
            "*idn?": lambda: IDENTITY,
            "ens?": lambda: "1" if self.enabled else "0",
            "closed?": lambda: "0" if self.world.lamp.shutter_open else "1",
            "interlock?": lambda: "1" if self.interlock else "0",
            "mode?": lambda: str(self.mode),
        }
        if command in queries:
            return queries[command]()
        if command == "ens":
            if not self.interlock:
                self.enabled = not self.enabled
                self._apply()
            return None
        name, sep, value = command.partition("=")
        if sep and name == "mode":
            if value in ("1", "2", "3", "4", "5"):
                self.mode = int(value)
                self._apply()
                return None
            return "Command error CMD_ARG_INVALID"
        return "Command error CMD_NOT_DEFINED"


ShutterSimulator = ThorlabsSC10Simulator  # the name drivers.sim.bench builds the xenon bench with
