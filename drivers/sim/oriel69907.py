"""Protocol front of the simulated Oriel 69907 arc-lamp supply (anchors-protocols §4.1, §6 item 3).

Device analysis (lewis style: the protocol first, then the state):

* CR-framed lines. ``NAME?`` answers ``value\\r``; ``STB?`` / ``ESR?`` answer ``STBxx`` / ``ESRxx``
  (two upper-case hex digits); sets (``A-PRESET=5.5``, ``P-PRESET=0095``, ``A-LIM=``, ``P-LIM=``) and
  actions (``START``, ``STOP``) answer ``ESRxx``: the event status register, which a read clears (IEEE-488.2).
* State: the lamp (the world's :class:`~drivers.sim.lamp.LampModel`: on, current, fault, interlock),
  presets and limits, the ESR. The ESR starts with the power-on bit set, as after switching the supply on.
* ``START`` with a lamp fault or an open interlock sets the execution-error bit and strikes nothing (the
  lamp model refuses too). A preset above its limit sets the execution-error bit; an unknown command or
  a value that does not parse sets the command-error bit. An unknown *query* answers ``ESRxx`` with the
  command-error bit (what the real supply answers is UNCONFIRMED).
* STB bit 7 "lamp on" follows the lamp model's `on` at once (the ignition delay is in the light output);
  bit 3 fault and bit 0 interlock come from the lamp's back door. Bit 0 is *set when the interlock is
  closed* (the reading of the 69920 driver; UNCONFIRMED for the 69907, see drivers.oriel69907); the class
  attribute `interlock_bit_set_means_closed` flips it.
* The supply runs in current mode (STB bit 5 clear): ``A-PRESET`` sets the lamp current, ``P-PRESET`` is
  stored only (``MODE=`` is not confirmed for the 69907, §4.1).
* Readings: ``AMPS?`` the lamp current with one decimal (0.0 when off), ``VOLTS?`` an arc voltage of
  15 V + 0.8 V/A (≈ 19 V at 5 A, a typical short-arc xenon figure; whole volts, as RTS2 reads it),
  ``WATTS?`` their product (whole watts), ``LAMP HRS?`` whole hours, ``IDN?`` the model number.

In instant mode (clock time scale 0) asking ``STB?`` while the lamp is on completes the warm-up: the
clock jumps to the moment the lamp model counts as warm, as observing an axis completes its move.

Back door: the WireFaults of every simulator, and ``world.lamp.inject_fault()`` / ``.interlock_open``.
"""

from __future__ import annotations

import re

from .device import LineDevice
from .world import SimWorld

MODEL = "69907"
DEFAULT_A_LIMIT = 12.0  # A; the lantz driver's maximum (anchors-protocols §4.1)
DEFAULT_P_LIMIT = 100  # W

STB_LAMP_ON, STB_FAULT, STB_INTERLOCK = 0x80, 0x08, 0x01
ESR_POWER_ON, ESR_COMMAND_ERROR, ESR_EXECUTION_ERROR = 0x80, 0x20, 0x10

_FLOAT = re.compile(r"^\d+(\.\d*)?$")
_INT = re.compile(r"^\d+$")


class Oriel69907Simulator(LineDevice):
    """The 69907 supply of the simulated xenon sun simulator; it drives ``world.lamp``."""

    name = "oriel69907"
    in_terminator = b"\r"
    out_terminator = b"\r"
    interlock_bit_set_means_closed = True

    def __init__(self, world: SimWorld):
        super().__init__()
        self.world = world
        self.lamp = world.lamp
        self.esr = ESR_POWER_ON
        self.a_limit = DEFAULT_A_LIMIT
        self.p_limit = DEFAULT_P_LIMIT
        self.p_preset = 75
        self.commands = 0  # lines handled, for tests that check nothing reached the supply

    # -- state seen over the wire ----------------------------------------------------------------------
    def stb(self) -> int:
        lamp = self.lamp
        if lamp.on and self.world.clock.instant:
            lamp.is_warm()  # observing completes the warm-up in instant mode
        value = STB_LAMP_ON if lamp.on else 0
        if lamp.fault:
            value |= STB_FAULT
        if lamp.interlock_open != self.interlock_bit_set_means_closed:
            value |= STB_INTERLOCK
        return value

    def _amps(self) -> float:
        return self.lamp.current_a if self.lamp.on and not self.lamp.fault else 0.0

    def _volts(self) -> float:
        amps = self._amps()
        return 15.0 + 0.8 * amps if amps > 0 else 0.0

    def _hours(self) -> float:
        lamp = self.lamp
        running = (self.world.clock.now() - lamp.t_on) / 3600.0 if lamp.on else 0.0
        return lamp.hours + max(running, 0.0)

    # -- protocol --------------------------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes:
        self.commands += 1
        text = line.decode("ascii", errors="replace").strip()
        return self._dispatch(text).encode("ascii") + self.out_terminator

    def _esr_reply(self, bits: int = 0) -> str:
        self.esr |= bits
        value, self.esr = self.esr, 0  # reading the register clears it
        return f"ESR{value:02X}"

    def _dispatch(self, text: str) -> str:
        queries = {
            "IDN?": lambda: MODEL,
            "STB?": lambda: f"STB{self.stb():02X}",
            "ESR?": self._esr_reply,
            "AMPS?": lambda: f"{self._amps():.1f}",
            "VOLTS?": lambda: f"{self._volts():.0f}",
            "WATTS?": lambda: f"{self._amps() * self._volts():.0f}",
            "LAMP HRS?": lambda: f"{self._hours():.0f}",
            "A-PRESET?": lambda: f"{self.lamp.current_a:.1f}",
            "P-PRESET?": lambda: f"{self.p_preset:04d}",
            "A-LIM?": lambda: f"{self.a_limit:.1f}",
            "P-LIM?": lambda: f"{self.p_limit:04d}",
        }
        if text in queries:
            return queries[text]()
        if text == "START":
            if self.lamp.fault or self.lamp.interlock_open:
                return self._esr_reply(ESR_EXECUTION_ERROR)
            self.lamp.start()
            return self._esr_reply()
        if text == "STOP":
            self.lamp.stop()
            return self._esr_reply()
        name, sep, value = text.partition("=")
        if sep and name in ("A-PRESET", "A-LIM") and _FLOAT.match(value):
            amps = float(value)
            if name == "A-LIM":
                self.a_limit = amps
            elif amps > self.a_limit:
                return self._esr_reply(ESR_EXECUTION_ERROR)
            else:
                self.lamp.current_a = amps
            return self._esr_reply()
        if sep and name in ("P-PRESET", "P-LIM") and _INT.match(value):
            watts = int(value)
            if name == "P-LIM":
                self.p_limit = watts
            elif watts > self.p_limit:
                return self._esr_reply(ESR_EXECUTION_ERROR)
            else:
                self.p_preset = watts
            return self._esr_reply()
        return self._esr_reply(ESR_COMMAND_ERROR)
