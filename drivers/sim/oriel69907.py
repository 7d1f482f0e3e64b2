"""Protocol front of the simulated Oriel 69907 arc-lamp supply (anchors-protocols §4.1, §6 item 3).

Device analysis (lewis style: the protocol first, then the state):

* CR-framed lines. ``NAME?`` answers ``value\\r``; ``STB?`` / ``ESR?`` answer ``STBxx`` / ``ESRxx``
  (two upper-case hex digits); sets and actions answer ``ESRxx``: the event status register, which a read
  clears (IEEE-488.2). The ESR starts with the power-on bit set, as after switching the supply on.
* The documented command set (lantz ``newport69907.py`` and RTS2 ``newport-lamp.cpp``):

  ==================================  ===============================================================
  ``IDN?``                            the model number (RTS2 reads it as an integer)
  ``STB?`` / ``ESR?``                 status byte / event status register (see below)
  ``AMPS?`` ``VOLTS?`` ``WATTS?``     output readings: one decimal, whole volts (RTS2's reading), whole watts
  ``LAMP HRS?``                       hours on the lamp, whole
  ``A-PRESET?`` / ``A-PRESET=5.5``    current preset [A], one decimal
  ``P-PRESET?`` / ``P-PRESET=0095``   power preset [W], four digits (a plain integer is accepted too)
  ``A-LIM?`` / ``A-LIM=12.0``         current limit [A]
  ``P-LIM?`` / ``P-LIM=0100``         power limit [W]
  ``START`` / ``STOP``                strike / put out the lamp
  ``RST``                             factory defaults (lantz ``reset``)
  ==================================  ===============================================================

  ``MODE=0|1`` (power / current mode) and ``COMM=1|0`` (lock / unlock the front panel) are documented for
  the sibling 69920 supply only (anchors-protocols §4.1: UNCONFIRMED for the 69907); they answer the
  command error unless the simulator is built with ``sibling_commands=True``, and then ``MODE=`` while the
  lamp burns is refused with the execution-error bit (the 69920 driver stops the lamp first; UNCONFIRMED).
  The operator can still switch the mode at the front panel (back door :meth:`front_panel_mode`).
* Regulation, and the limits enforced. In current mode (STB bit 5 clear) the supply drives ``A-PRESET``; in
  power mode the current that gives ``P-PRESET``. Either way the output never exceeds ``A-LIM`` nor
  ``P-LIM``: when one of them holds it back the supply runs at the limit and sets STB bit 1 "limit" (while
  the lamp burns), as the front-panel LIMIT lamp does. A preset above its limit is refused with the
  execution-error bit (nothing changes); a limit above the supply's rating (`rating_a`, `rating_w`) too; a
  limit set below the running preset is accepted and limits the output at once.
* The lamp: the world's :class:`~drivers.sim.lamp.LampModel` (on, current, fault, interlock), whose current is
  the regulated output current. Its arc voltage is 15 V + 0.8 V/A (≈ 19 V at 5 A, a typical short-arc
  xenon figure), so 5 A is 95 W.
* ``START`` with a lamp fault or an open interlock sets the execution-error bit and strikes nothing (the
  lamp model refuses too). An unknown command, or a value that does not parse, sets the command-error bit;
  an unknown *query* answers ``ESRxx`` with the command-error bit (what the real supply answers is
  UNCONFIRMED).
* ``RST`` restores the factory presets and limits (:data:`FACTORY`), current mode and an unlocked panel;
  whether it also puts out a burning lamp is UNCONFIRMED: here the lamp keeps burning, at the restored
  preset.
* STB bit 7 "lamp on" follows the lamp model's `on` at once (the ignition delay is in the light output);
  bit 3 fault and bit 0 interlock come from the lamp's back door; bit 2 is the panel lock (``COMM=1``).
  Bit 0 is *set when the interlock is closed* (the reading of the 69920 driver; UNCONFIRMED for the 69907,
  see drivers.oriel69907); the class attribute `interlock_bit_set_means_closed` flips it.

In instant mode (clock time scale 0) asking ``STB?`` while the lamp is on completes the warm-up: the
clock jumps to the moment the lamp model counts as warm, as observing an axis completes its move.

Back door: the WireFaults of every simulator, :meth:`front_panel_mode`, and ``world.lamp.inject_fault()`` /
``.interlock_open``.
"""

from __future__ import annotations

import math
import re

from ..oriel69907 import (  # the register bits (anchors-protocols §4.1), as the driver decodes them
    ESR_COMMAND_ERROR,
    ESR_EXECUTION_ERROR,
    ESR_POWER_ON,
    STB_COMM,
    STB_FAULT,
    STB_INTERLOCK,
    STB_LAMP_ON,
    STB_LIMIT,
    STB_POWER_MODE,
)
from .device import LineDevice
from .world import SimWorld

MODEL = "69907"
DEFAULT_A_LIMIT = 12.0  # A; the lantz driver's lamp (max_lamp_amps, anchors-protocols §4.1)
DEFAULT_P_LIMIT = 100  # W; the lantz driver's lamp (max_lamp_power)
DEFAULT_P_PRESET = 75  # W
# The factory settings RST restores; the current preset is the simulated lamp's nominal current.
FACTORY = {"a_limit": DEFAULT_A_LIMIT, "p_limit": DEFAULT_P_LIMIT, "p_preset": DEFAULT_P_PRESET}
# Highest limits the supply accepts. The OPS-A family is sold for lamps of up to 500 W; the current rating
# is a placeholder (UNCONFIRMED), above any lamp this bench would fit.
RATING_A = 50.0
RATING_W = 500

ARC_V0, ARC_V_PER_A = 15.0, 0.8  # arc voltage = ARC_V0 + ARC_V_PER_A * current [V]

_FLOAT = re.compile(r"^\d+(\.\d*)?$")
_INT = re.compile(r"^\d+$")


def arc_volts(amps: float) -> float:
    """Arc voltage of the simulated lamp at `amps` [V] (0 when no current flows)."""
    return ARC_V0 + ARC_V_PER_A * amps if amps > 0 else 0.0


def amps_for_watts(watts: float) -> float:
    """The current at which the simulated lamp takes `watts` [A]: the root of 0.8 I² + 15 I = P."""
    if watts <= 0:
        return 0.0
    return (-ARC_V0 + math.sqrt(ARC_V0 ** 2 + 4 * ARC_V_PER_A * watts)) / (2 * ARC_V_PER_A)


class Oriel69907Simulator(LineDevice):
    """The 69907 supply of the simulated xenon sun simulator; it drives ``world.lamp``.

    Parameters
    ----------
    world : SimWorld
    sibling_commands : bool
        Also accept the 69920's ``MODE=`` and ``COMM=`` (see the module docstring).
    rating_a, rating_w : float
        Highest current and power limits the supply accepts.
    """

    name = "oriel69907"
    in_terminator = b"\r"
    out_terminator = b"\r"
    interlock_bit_set_means_closed = True

    def __init__(self, world: SimWorld, *, sibling_commands: bool = False, rating_a: float = RATING_A,
                 rating_w: float = RATING_W):
        super().__init__()
        self.world = world
        self.lamp = world.lamp
        self.sibling_commands = sibling_commands
        self.rating_a = float(rating_a)
        self.rating_w = float(rating_w)
        self.esr = ESR_POWER_ON
        self.a_preset = self.lamp.current_a
        self.a_limit = DEFAULT_A_LIMIT
        self.p_limit = DEFAULT_P_LIMIT
        self.p_preset = DEFAULT_P_PRESET
        self.power_mode = False
        self.panel_locked = False
        self.limited = False  # the output is held back by A-LIM or P-LIM
        self.commands = 0  # lines handled, for tests that check nothing reached the supply
        self._regulate()

    # -- back door -------------------------------------------------------------------------------------
    def front_panel_mode(self, power: bool) -> None:
        """The operator switches the supply to power mode (True) or current mode at the front panel."""
        self.power_mode = bool(power)
        self._regulate()

    # -- regulation ------------------------------------------------------------------------------------
    def _regulate(self) -> None:
        """Set the lamp current from the mode, the presets and the limits; note whether a limit holds it."""
        wanted = amps_for_watts(self.p_preset) if self.power_mode else self.a_preset
        amps = min(wanted, self.a_limit, amps_for_watts(self.p_limit))
        self.limited = amps < wanted - 1e-9
        self.lamp.current_a = amps

    # -- state seen over the wire ----------------------------------------------------------------------
    def stb(self) -> int:
        lamp = self.lamp
        if lamp.on and self.world.clock.instant:
            lamp.is_warm()  # observing completes the warm-up in instant mode
        value = STB_LAMP_ON if lamp.on else 0
        if self.power_mode:
            value |= STB_POWER_MODE
        if lamp.fault:
            value |= STB_FAULT
        if self.panel_locked:
            value |= STB_COMM
        if lamp.on and self.limited:
            value |= STB_LIMIT
        if lamp.interlock_open != self.interlock_bit_set_means_closed:
            value |= STB_INTERLOCK
        return value

    def _amps(self) -> float:
        return self.lamp.current_a if self.lamp.on and not self.lamp.fault else 0.0

    def _volts(self) -> float:
        return arc_volts(self._amps())

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
            "A-PRESET?": lambda: f"{self.a_preset:.1f}",
            "P-PRESET?": lambda: f"{self.p_preset:04d}",
            "A-LIM?": lambda: f"{self.a_limit:.1f}",
            "P-LIM?": lambda: f"{self.p_limit:04d}",
        }
        if text in queries:
            return queries[text]()
        if text == "START":
            if self.lamp.fault or self.lamp.interlock_open:
                return self._esr_reply(ESR_EXECUTION_ERROR)
            self._regulate()
            self.lamp.start()
            return self._esr_reply()
        if text == "STOP":
            self.lamp.stop()
            return self._esr_reply()
        if text == "RST":
            self.a_preset = self.lamp.spec.nominal_current_a
            self.a_limit, self.p_limit, self.p_preset = FACTORY["a_limit"], FACTORY["p_limit"], FACTORY["p_preset"]
            self.power_mode = self.panel_locked = False
            self._regulate()
            return self._esr_reply()
        name, sep, value = text.partition("=")
        if not sep:
            return self._esr_reply(ESR_COMMAND_ERROR)
        if name in ("A-PRESET", "A-LIM") and _FLOAT.match(value):
            return self._esr_reply(self._set_amps(name, float(value)))
        if name in ("P-PRESET", "P-LIM") and _INT.match(value):
            return self._esr_reply(self._set_watts(name, int(value)))
        if self.sibling_commands and name in ("MODE", "COMM") and value in ("0", "1"):
            if name == "MODE":
                if self.lamp.on:  # the 69920 driver stops the lamp before changing the mode
                    return self._esr_reply(ESR_EXECUTION_ERROR)
                self.power_mode = value == "0"  # MODE=0 power, MODE=1 current (the 69920 driver)
            else:
                self.panel_locked = value == "1"
            self._regulate()
            return self._esr_reply()
        return self._esr_reply(ESR_COMMAND_ERROR)

    def _set_amps(self, name: str, amps: float) -> int:
        """A-PRESET / A-LIM; returns the ESR bits to add."""
        if name == "A-LIM":
            if amps > self.rating_a:
                return ESR_EXECUTION_ERROR
            self.a_limit = amps
        elif amps > self.a_limit:
            return ESR_EXECUTION_ERROR
        else:
            self.a_preset = amps
        self._regulate()
        return 0

    def _set_watts(self, name: str, watts: int) -> int:
        """P-PRESET / P-LIM; returns the ESR bits to add."""
        if name == "P-LIM":
            if watts > self.rating_w:
                return ESR_EXECUTION_ERROR
            self.p_limit = watts
        elif watts > self.p_limit:
            return ESR_EXECUTION_ERROR
        else:
            self.p_preset = watts
        self._regulate()
        return 0
