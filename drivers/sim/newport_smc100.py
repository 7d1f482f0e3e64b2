"""Wire-level simulator of a Newport SMC100 controller with one rotation stage (anchors-protocols §3.1, §6).

Protocol front only: the physics is an :class:`~drivers.sim.motion.AxisModel` on the world's clock, the
back door is :attr:`Smc100Simulator.faults` and :attr:`Smc100Simulator.axis` (``stall()``,
``trip_limit()``).

Device analysis (the manual is the SMC100CC/PP user's manual, EDH0206En, §6.3 "Command syntax"; what the
public clients pystages, QMI and pymeasure send and expect is in research/peer-clients.md):

* Lines ``[<address>]<CC>[?]<value>\\r\\n``; upper and lower case are accepted and blanks are ignored
  anywhere, even inside a number (manual §6.3: ``2P A1.43 6`` = ``2PA1.436``). An empty line is ignored
  without an error (QMI ends every command with its own CR LF, so each is followed by one; a real controller
  is used that way, though no manual line says so: UNCONFIRMED). Lines for another address are ignored
  (another controller on the RS-485 chain); a line that does not parse, or an unknown command, sets TE ``A``.
* Address-less commands: the manual's command format has an "optional or required controller address";
  ``MM`` and ``ST`` (with ``SE``, not simulated, the commands that may be broadcast to every chained
  controller, as pymeasure's SMC100 docstring reads the manual) are executed without an address, or with
  address 0 (pymeasure's broadcast form, UNCONFIRMED), and never answer; pystages sends them so (``ST``,
  ``MM1``).
  Any other command without an address sets TE ``B`` (controller address not correct; which letter a real
  controller memorizes is UNCONFIRMED).
* Queries answer with the address and command echoed: ``1TP12.5\\r\\n``. ``TP``, ``TS``, ``TE``, ``VE`` are
  accepted with or without ``?`` (pystages sends ``TS?``, QMI and pymeasure ``TS``; a real controller answers
  ``1VE?``).
* States (hex codes of TS): 0A NOT REFERENCED from reset → ``OR`` → 1E HOMING → 32 READY from homing;
  READY → ``PA``/``PR`` → 28 MOVING → 33 READY from moving; ``ST`` while MOVING → 33, while HOMING →
  0B NOT REFERENCED from homing; ``RS`` → 0A from anywhere.
  CONFIGURATION: ``PW1`` from NOT REFERENCED → 14; ``PW0`` → 0C NOT REFERENCED from configuration (a real
  controller writes its flash then, up to 10 s without answering; the simulator is done at once).
  ``PW?`` answers 1 in CONFIGURATION, else 0.
  DISABLE: ``MM0`` READY → 3C DISABLE from ready (MOVING → 3D DISABLE from moving, the motion stopped where
  it is: UNCONFIRMED which event gives 3D on a real controller); ``MM1`` DISABLE → 34 READY from disable.
  ``MM0`` in DISABLE and ``MM1`` in READY change nothing and are no error (UNCONFIRMED).
  ``MM?`` answers 0 in DISABLE, else 1 (UNCONFIRMED). CONFLICT: pystages, pymeasure and two other public
  drivers read MM0 as "enter DISABLE", which the simulator follows; QMI sends ``MM1`` to enter DISABLE and
  reads ``MM?`` = 1 as disabled (anchors-protocols §3.1).
* Refusals set TE (pymeasure's letters): ``PA``/``PR`` unless READY → H (NOT REFERENCED), I, J, L (HOMING),
  M (MOVING); ``OR`` unless NOT REFERENCED → E in HOMING, K in READY, M in MOVING …; a target the axis
  refuses (soft limits, into the tripped switch) → G; a missing or bad number → C. TE reports the last
  error and clears it (UNCONFIRMED, but it is how TE is used by QMI and pymeasure).
* ``TB<c>`` answers ``1TB<c> <text>`` with the manual's text of the letter (QMI splits on the first blank);
  ``TB`` or ``TB?`` without a letter answers the last error the same way and clears it, as TE does (the
  Newport LDS1000 manual says its TB and TE both reset the error; for the SMC100 UNCONFIRMED).
* Parameters, ``xxCC?`` → ``xxCC<value>``:
  ``VA`` velocity and ``AC`` acceleration are the axis model's rate and acceleration (setting them changes the
  motion); ``JR`` jerk time, ``BA`` backlash compensation, ``BH`` hysteresis compensation and ``OT`` HOME
  search time-out (the manual's meaning of OT; QMI's ``get_home_search_timeout`` agrees) are held and
  answered but do not shape the motion (the model's moves are trapezoidal; its backlash is mechanical truth).
  ``VA``, ``AC``, ``JR`` may be set in any state but HOMING and MOVING; ``BA``, ``BH``, ``OT`` and ``SA`` only
  in CONFIGURATION (BA and BH so on a real SMC100CC; for OT and SA as QMI sets them: UNCONFIRMED), else
  the state's refusal letter. BA and BH exclude each other: setting one non-zero while the other is non-zero
  is refused with D (UNCONFIRMED letter). Ranges (pymeasure's, from the manual): VA, AC > 1e-6, JR > 1e-3,
  BA, BH ≥ 0, 1 < OT < 1000, all < 1e12; outside → C.
* ``SA?`` answers the controller address; ``SAnn`` (2–31, pystages' range) takes effect when CONFIGURATION is
  left with ``PW0`` (UNCONFIRMED: the manual's exact moment).
* ``PTnn`` answers ``1PT<t>``, the time [s] a relative move of nn takes at the present VA and AC (the axis
  model's trapezoid, settling excluded); it moves nothing and is answered in every state.
* TS error bits: bit 0 negative end of run / bit 1 positive end of run from the axis model's `limit_hit`
  ("low"/"high"). A move that ends on a limit switch ends in READY from MOVING with the bit set (the real
  end state is UNCONFIRMED).
* Replies print numbers with 6 decimals (the real format is UNCONFIRMED).
"""

from __future__ import annotations

import dataclasses
import math
import re

from .. import newport_smc100 as controller
from ..newport_smc100 import COMMAND_ERRORS, state_name
from .device import LineDevice
from .motion import AxisLimitError, AxisSpec, trapezoid

NOT_REFERENCED_FROM_RESET = 0x0A
NOT_REFERENCED_FROM_HOMING = 0x0B
NOT_REFERENCED_FROM_CONFIGURATION = 0x0C
CONFIGURATION = 0x14
HOMING = 0x1E
MOVING = 0x28
READY_FROM_HOMING = 0x32
READY_FROM_MOVING = 0x33
READY_FROM_DISABLE = 0x34
DISABLE_FROM_READY = 0x3C
DISABLE_FROM_MOVING = 0x3D

#: Text of each TE letter as TB gives it, in the manual's wording: the driver's table of meanings (pymeasure's)
#: with the first word capitalised, C and S worded as the manual (and lantz's table) word them.
ERROR_TEXTS: dict[str, str] = {
    **{letter: meaning[0].upper() + meaning[1:] for letter, meaning in COMMAND_ERRORS.items()},
    "C": "Parameter missing or out of range",
    "S": "Communication Time Out",
}

#: Commands a host may send without an address (or with address 0) to every controller of the chain.
BROADCAST = frozenset({"MM", "ST"})

_LINE = re.compile(r"^(\d{1,2})?([A-Za-z]{2})(\??)(.*)$")


#: TE letter of a command the present state does not allow, by the state's name (anchors-protocols §3.1)
_REFUSALS = {controller.NOT_REFERENCED: "H", controller.CONFIGURATION: "I", controller.DISABLE: "J",
             controller.READY: "K", controller.HOMING: "L", controller.MOVING: "M"}


def _refusal_letter(state: int) -> str:
    """TE letter for a command that the present state does not allow (D in a state that has none)."""
    return _REFUSALS.get(state_name(state), "D")


class Smc100Simulator(LineDevice):
    """Protocol front of one simulated SMC100 controller driving one axis of the world.

    Parameters
    ----------
    world : SimWorld
        The shared truth; the controller creates its axis with ``world.new_axis(spec)``.
    spec : AxisSpec
        Mechanics of the stage; `max_rate_deg_s` is what ``VA?`` reports and ``VA`` changes.
    address : int
        Controller address.
    stage_id : str
        Reply of ``ID?``.
    version : str
        Reply of ``VE``.
    jerk_time_s, home_timeout_s : float
        Initial ``JR`` and ``OT`` (held and answered; they do not shape the motion).

    Attributes
    ----------
    axis : AxisModel
    state : int
        Controller state code (hex ``ef`` of TS).
    error : str
        Last command error letter (``@`` = none).
    backlash, hysteresis : float
        ``BA`` and ``BH`` compensation [°] (held and answered only).
    """

    name = "newport-smc100"
    in_terminator = b"\r\n"

    def __init__(self, world, spec: AxisSpec, *, address: int = 1, stage_id: str = "URS100BCC_SIM",
                 version: str = "SMC_CC - Controller-driver version 2.0.0", jerk_time_s: float = 0.04,
                 home_timeout_s: float = 10.0):
        super().__init__()
        self.world = world
        self.axis = world.new_axis(spec)
        self.address = address
        self.stage_id = stage_id
        self.version = version
        self.state = NOT_REFERENCED_FROM_RESET
        self.error = "@"
        self.target_deg = 0.0
        self.jerk_time_s = jerk_time_s
        self.home_timeout_s = home_timeout_s
        self.backlash = 0.0
        self.hysteresis = 0.0
        self._new_address: int | None = None  # SA in CONFIGURATION, applied by PW0

    # -- state ----------------------------------------------------------------------------------------------
    def _refresh(self) -> None:
        """Advance the state machine with the axis: a finished move or homing ends in READY."""
        if self.state in (HOMING, MOVING) and not self.axis.busy():
            self.state = READY_FROM_HOMING if self.state == HOMING else READY_FROM_MOVING

    def error_bits(self) -> int:
        hit = self.axis.limit_hit
        return (1 if hit == "low" else 0) | (2 if hit == "high" else 0)

    def _ready(self) -> bool:
        return state_name(self.state) == controller.READY

    def _not_referenced(self) -> bool:
        return state_name(self.state) == controller.NOT_REFERENCED

    def _disabled(self) -> bool:
        return state_name(self.state) == controller.DISABLE

    # -- lines ----------------------------------------------------------------------------------------------
    def _reply(self, command: str, value: str) -> bytes:
        return f"{self.address}{command}{value}\r\n".encode("ascii")

    @staticmethod
    def _number(text: str) -> float | None:
        try:
            value = float(text)
        except ValueError:
            return None
        return value if math.isfinite(value) else None

    def handle_line(self, line: bytes) -> bytes:
        text = "".join(line.decode("ascii", "replace").split())  # blanks are ignored anywhere (manual §6.3)
        if not text:
            return b""  # an empty line (QMI sends one after every command)
        match = _LINE.match(text)
        if not match:
            self.error = "A"
            return b""
        address = int(match[1]) if match[1] else None
        command, query, value = match[2].upper(), match[3] == "?", match[4]
        if address in (None, 0):
            if command in BROADCAST and not query:
                self._refresh()
                getattr(self, f"_cmd_{command}")(False, value)
                return b""  # a broadcast command is never answered
            if address is None:
                self.error = "B"
            return b""
        if address != self.address:
            return b""  # not for us
        self._refresh()
        handler = getattr(self, f"_cmd_{command}", None)
        if handler is None:
            self.error = "A"
            return b""
        return handler(query, value)

    # -- commands (anchors-protocols §3.1) -------------------------------------------------------------------
    def _cmd_ID(self, query: bool, value: str) -> bytes:
        return self._reply("ID", self.stage_id) if query else b""

    def _cmd_VE(self, query: bool, value: str) -> bytes:
        return self._reply("VE", " " + self.version)

    def _cmd_TP(self, query: bool, value: str) -> bytes:
        return self._reply("TP", f"{self.axis.position_deg():.6f}")

    def _cmd_TH(self, query: bool, value: str) -> bytes:
        return self._reply("TH", f"{self.target_deg:.6f}")

    def _cmd_TS(self, query: bool, value: str) -> bytes:
        return self._reply("TS", f"{self.error_bits():04X}{self.state:02X}")

    def _cmd_TE(self, query: bool, value: str) -> bytes:
        letter, self.error = self.error, "@"
        return self._reply("TE", letter)

    def _new_value(self, value: str, low: float, *, high: float = 1e12, low_included: bool = False,
                   configuration_only: bool = False) -> float | None:
        """The number a parameter is set to, or None after setting TE: the state's refusal letter when the
        parameter cannot be set now (only in CONFIGURATION, or not while HOMING or MOVING), C when the number
        is missing or outside the range."""
        busy = state_name(self.state) in (controller.HOMING, controller.MOVING)
        if (self.state != CONFIGURATION) if configuration_only else busy:
            self.error = _refusal_letter(self.state)
            return None
        number = self._number(value)
        if number is None or not (low <= number if low_included else low < number) or not number < high:
            self.error = "C"
            return None
        return number

    def _cmd_VA(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("VA", f"{self.axis.spec.max_rate_deg_s:.6f}")
        rate = self._new_value(value, 1e-6)
        if rate is not None:
            self.axis.spec = dataclasses.replace(self.axis.spec, max_rate_deg_s=rate)
        return b""

    def _cmd_AC(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("AC", f"{self.axis.spec.accel_deg_s2:.6f}")
        accel = self._new_value(value, 1e-6)
        if accel is not None:
            self.axis.spec = dataclasses.replace(self.axis.spec, accel_deg_s2=accel)
        return b""

    def _cmd_JR(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("JR", f"{self.jerk_time_s:.6f}")
        jerk = self._new_value(value, 1e-3)
        if jerk is not None:
            self.jerk_time_s = jerk
        return b""

    def _cmd_OT(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("OT", f"{self.home_timeout_s:.6f}")
        timeout = self._new_value(value, 1.0, high=1e3, configuration_only=True)
        if timeout is not None:
            self.home_timeout_s = timeout
        return b""

    def _compensation(self, value: str, other: float) -> float | None:
        amount = self._new_value(value, 0.0, low_included=True, configuration_only=True)
        if amount is not None and amount > 0 and other > 0:
            self.error = "D"  # backlash and hysteresis compensation exclude each other
            return None
        return amount

    def _cmd_BA(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("BA", f"{self.backlash:.6f}")
        amount = self._compensation(value, self.hysteresis)
        if amount is not None:
            self.backlash = amount
        return b""

    def _cmd_BH(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("BH", f"{self.hysteresis:.6f}")
        amount = self._compensation(value, self.backlash)
        if amount is not None:
            self.hysteresis = amount
        return b""

    def _cmd_SA(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("SA", str(self._new_address or self.address))
        address = self._new_value(value, 2.0, high=32.0, low_included=True, configuration_only=True)
        if address is not None:
            if address != int(address):
                self.error = "C"
            else:
                self._new_address = int(address)
        return b""

    def _cmd_PT(self, query: bool, value: str) -> bytes:
        distance = None if query else self._number(value)
        if distance is None:
            self.error = "C"
            return b""
        spec = self.axis.spec
        return self._reply("PT", f"{trapezoid(distance, spec.max_rate_deg_s, spec.accel_deg_s2):.6f}")

    def _cmd_TB(self, query: bool, value: str) -> bytes:
        code = value.upper()
        if not code:  # the last error, which is then cleared (UNCONFIRMED, see the module docstring)
            code, self.error = self.error, "@"
        elif code not in ERROR_TEXTS:
            self.error = "C"
            return b""
        return self._reply("TB", f"{code} {ERROR_TEXTS[code]}")

    def _cmd_PW(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("PW", "1" if self.state == CONFIGURATION else "0")
        if value == "1":  # NOT REFERENCED → CONFIGURATION
            if self._not_referenced():
                self.state = CONFIGURATION
            elif self.state != CONFIGURATION:
                self.error = _refusal_letter(self.state)
        elif value == "0":  # CONFIGURATION → NOT REFERENCED (the real one writes its flash now)
            if self.state == CONFIGURATION:
                self.state = NOT_REFERENCED_FROM_CONFIGURATION
                if self._new_address is not None:
                    self.address, self._new_address = self._new_address, None
            else:
                self.error = _refusal_letter(self.state)
        else:
            self.error = "C"
        return b""

    def _cmd_MM(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("MM", "0" if self._disabled() else "1")
        if value == "0":  # READY → DISABLE
            if self._ready():
                self.state = DISABLE_FROM_READY
            elif self.state == MOVING:
                self.axis.stop()
                self.state = DISABLE_FROM_MOVING
            elif not self._disabled():
                self.error = _refusal_letter(self.state)
        elif value == "1":  # DISABLE → READY
            if self._disabled():
                self.state = READY_FROM_DISABLE
            elif not self._ready():
                self.error = _refusal_letter(self.state)
        else:
            self.error = "C"
        return b""

    def _cmd_OR(self, query: bool, value: str) -> bytes:
        if self.state == HOMING:
            self.error = "E"
        elif not self._not_referenced():
            self.error = _refusal_letter(self.state)
        else:
            self.axis.home()
            self.state = HOMING
        return b""

    def _move(self, target_deg: float | None) -> bytes:
        if not self._ready():
            self.error = _refusal_letter(self.state)
        elif target_deg is None:
            self.error = "C"
        else:
            try:
                self.axis.move_to(target_deg)
            except AxisLimitError:
                self.error = "G"
                return b""
            self.target_deg = target_deg
            self.state = MOVING
        return b""

    def _cmd_PA(self, query: bool, value: str) -> bytes:
        return self._move(self._number(value))

    def _cmd_PR(self, query: bool, value: str) -> bytes:
        delta = self._number(value)
        return self._move(None if delta is None else self.axis.position_deg() + delta)

    def _cmd_ST(self, query: bool, value: str) -> bytes:
        self.axis.stop()
        if self.state == MOVING:
            self.state = READY_FROM_MOVING
        elif self.state == HOMING:
            self.state = NOT_REFERENCED_FROM_HOMING
        return b""

    def _cmd_RS(self, query: bool, value: str) -> bytes:
        self.axis.stop()
        self.state = NOT_REFERENCED_FROM_RESET
        self.error = "@"
        self._new_address = None
        return b""
