"""Protocol front of the simulated SCPI bench supply that drives the LED sun simulator
(anchors-protocols §4.2; wire details in :mod:`drivers.scpi_supply`).

Device analysis:

* Lines end with LF (a CR before it is ignored); replies end with `out_terminator` (LF by default).
  Headers are case-insensitive and take the short or the long form (``OUTP`` / ``OUTPut``,
  ``MEAS:CURR?`` / ``MEASure:CURRent?``), with an optional leading colon.
* ``*IDN?``, ``*CLS``, ``SYST:REM``, ``APPL [<output>,]<V>,<A>``, ``CURR <A>`` / ``CURR?``,
  ``VOLT <V>`` / ``VOLT?``, ``OUTP ON|OFF|1|0`` / ``OUTP?``, ``MEAS:CURR? [<output>]``,
  ``MEAS:VOLT? [<output>]``, ``SYST:ERR?``.
* Errors go to a queue (``SYST:ERR?`` pops the oldest, ``+0,"No error"`` when empty), with the standard
  SCPI codes: -113 undefined header, -104 data type error, -222 data out of range, -221 settings
  conflict, and -350 queue overflow when more than `queue_size` pile up.
* The output drives the world's LED: ``OUTP ON`` starts the lamp model (``LampModel.start``), sets its
  current to the setpoint and opens its "shutter" (``shutter_open``: the LED shines); ``OUTP OFF`` stops it
  and closes it. Constant-current operation: with the output on, ``MEAS:CURR?`` reads the setpoint and
  ``MEAS:VOLT?`` the LED string's forward voltage (2.9 V + 1 V/A). A failed LED (``lamp.inject_fault()``)
  is an open string: no current flows and the voltage sits at the compliance setpoint.
* ``OUTP ON`` while the lamp's interlock is open (a remote-inhibit input of the supply, wired to the bench
  interlock) is refused with -221 and leaves the output off.

In instant mode (clock time scale 0) asking ``OUTP?`` while the output is on completes the LED's warm-up,
as observing an axis completes its move.

Back door: the WireFaults of every simulator, ``world.lamp.inject_fault()`` / ``.interlock_open``.
"""

from __future__ import annotations

import re

from .device import LineDevice
from .world import SimWorld

IDENTITY = "SUNBENCH,SCPI-SUPPLY-SIM,0,1.0"
MAX_CURRENT_A = 3.0
MAX_VOLTAGE_V = 30.0

_LONG = {"OUTPUT": "OUTP", "MEASURE": "MEAS", "CURRENT": "CURR", "VOLTAGE": "VOLT", "SYSTEM": "SYST",
         "ERROR": "ERR", "APPLY": "APPL", "REMOTE": "REM", "STATE": "STAT"}
_NUMBER = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")

ERRORS = {-104: "Data type error", -113: "Undefined header", -221: "Settings conflict",
          -222: "Data out of range", -350: "Queue overflow"}


class ScpiSupplySimulator(LineDevice):
    """The bench supply of the simulated LED sun simulator; it drives ``world.lamp``."""

    name = "scpi-supply"
    in_terminator = b"\n"

    def __init__(self, world: SimWorld, *, out_terminator: bytes = b"\n", queue_size: int = 20):
        super().__init__()
        self.world = world
        self.lamp = world.lamp
        self.out_terminator = out_terminator
        self.queue_size = queue_size
        self.errors: list[int] = []
        self.output = False
        self.current_a = 0.0
        self.voltage_v = 5.0
        self.remote = False
        self.commands = 0

    # -- state -----------------------------------------------------------------------------------------
    def _error(self, code: int) -> None:
        if len(self.errors) < self.queue_size:
            self.errors.append(code)
        else:
            self.errors[-1] = -350

    def _set_output(self, on: bool) -> None:
        if on and self.lamp.interlock_open:
            self._error(-221)
            return
        self.output = on
        if on:
            self.lamp.current_a = self.current_a
            self.lamp.start()
        else:
            self.lamp.stop()
        self.lamp.shutter_open = on

    def _measured_current(self) -> float:
        return self.current_a if self.output and self.lamp.on and not self.lamp.fault else 0.0

    def _measured_voltage(self) -> float:
        if not self.output:
            return 0.0
        if self._measured_current() == 0.0:
            return self.voltage_v  # open string: the supply sits at its compliance voltage
        return min(2.9 + 1.0 * self.current_a, self.voltage_v)

    # -- protocol --------------------------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes:
        self.commands += 1
        text = line.decode("ascii", errors="replace").strip()
        reply = self._dispatch(text) if text else None
        return b"" if reply is None else reply.encode("ascii") + self.out_terminator

    @staticmethod
    def _header(raw: str) -> str:
        parts = raw.upper().lstrip(":").split(":")
        out = []
        for part in parts:
            query = part.endswith("?")
            word = part.rstrip("?")
            out.append(_LONG.get(word, word) + ("?" if query else ""))
        return ":".join(out)

    def _number(self, text: str, high: float) -> float | None:
        if not _NUMBER.match(text):
            self._error(-104)
            return None
        value = float(text)
        if not 0.0 <= value <= high:
            self._error(-222)
            return None
        return value

    def _dispatch(self, text: str) -> str | None:
        raw_header, _, argument = text.partition(" ")
        header, argument = self._header(raw_header), argument.strip()
        if header == "*IDN?":
            return IDENTITY
        if header == "*CLS":
            self.errors.clear()
            return None
        if header == "SYST:ERR?":
            if not self.errors:
                return '+0,"No error"'
            code = self.errors.pop(0)
            return f'{code:+d},"{ERRORS[code]}"'
        if header == "SYST:REM":
            self.remote = True
            return None
        if header == "OUTP?":
            if self.output and self.world.clock.instant:
                self.lamp.is_warm()  # observing completes the warm-up in instant mode
            return "1" if self.output else "0"
        if header in ("OUTP", "OUTP:STAT"):
            word = argument.upper()
            if word in ("ON", "1"):
                self._set_output(True)
            elif word in ("OFF", "0"):
                self._set_output(False)
            else:
                self._error(-104)
            return None
        if header == "CURR?":
            return f"{self.current_a:+.8E}"
        if header == "VOLT?":
            return f"{self.voltage_v:+.8E}"
        if header == "CURR":
            value = self._number(argument, MAX_CURRENT_A)
            if value is not None:
                self.current_a = value
                if self.output:
                    self.lamp.current_a = value
            return None
        if header == "VOLT":
            value = self._number(argument, MAX_VOLTAGE_V)
            if value is not None:
                self.voltage_v = value
            return None
        if header == "APPL":
            fields = [f.strip() for f in argument.split(",")]
            if len(fields) == 3:  # multi-output form: APPL P6V,<V>,<A>; the output name is not checked
                fields = fields[1:]
            if len(fields) != 2:
                self._error(-104)
                return None
            voltage = self._number(fields[0], MAX_VOLTAGE_V)
            current = self._number(fields[1], MAX_CURRENT_A) if voltage is not None else None
            if voltage is not None and current is not None:
                self.voltage_v, self.current_a = voltage, current
                if self.output:
                    self.lamp.current_a = current
            return None
        if header == "MEAS:CURR?":
            return f"{self._measured_current():+.8E}"
        if header == "MEAS:VOLT?":
            return f"{self._measured_voltage():+.8E}"
        self._error(-113)
        return None
