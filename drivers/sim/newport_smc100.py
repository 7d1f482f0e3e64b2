"""Wire-level simulator of a Newport SMC100 controller with one rotation stage (anchors-protocols §3.1, §6).

Protocol front only: the physics is an :class:`~drivers.sim.motion.AxisModel` on the world's clock, the
back door is :attr:`Smc100Simulator.faults` and :attr:`Smc100Simulator.axis` (``stall()``,
``trip_limit()``).

Device analysis:

* Lines ``<address><CC>[?]<value>\\r\\n``; lines for another address are ignored (another controller on
  the RS-485 chain); a line that does not parse, or an unknown command, sets TE ``A``.
* Queries answer with the address and command echoed: ``1TP12.5\\r\\n``. ``TP``, ``TS``, ``TE`` are
  accepted with or without ``?`` (pystages sends ``TS?``, QMI and pymeasure ``TS``).
* States (hex codes of TS): 0A NOT REFERENCED from reset → ``OR`` → 1E HOMING → 32 READY from homing;
  READY → ``PA``/``PR`` → 28 MOVING → 33 READY from moving; ``ST`` while MOVING → 33, while HOMING →
  0B NOT REFERENCED from homing; ``RS`` → 0A from anywhere.
* Refusals set TE (pymeasure's letters): ``PA``/``PR`` unless READY → H (NOT REFERENCED), I, J, L (HOMING),
  M (MOVING); ``OR`` unless NOT REFERENCED → E in HOMING, K in READY, M in MOVING …; a target the axis
  refuses (soft limits, into the tripped switch) → G; a missing or bad number → C. TE reports the last
  error and clears it (UNCONFIRMED, but it is how TE is used by QMI and pymeasure).
* TS error bits: bit 0 negative end of run / bit 1 positive end of run from the axis model's `limit_hit`
  ("low"/"high"). A move that ends on a limit switch ends in READY from MOVING with the bit set (the real
  end state is UNCONFIRMED).
* Replies print numbers with 6 decimals (the real format is UNCONFIRMED).
"""

from __future__ import annotations

import dataclasses
import math
import re

from .device import LineDevice
from .motion import AxisLimitError, AxisSpec

NOT_REFERENCED_FROM_RESET = 0x0A
NOT_REFERENCED_FROM_HOMING = 0x0B
HOMING = 0x1E
MOVING = 0x28
READY_FROM_HOMING = 0x32
READY_FROM_MOVING = 0x33

_LINE = re.compile(r"^(\d{1,2})([A-Za-z]{2})(\??)(.*)$")


def _refusal_letter(state: int) -> str:
    """TE letter for a command that the present state does not allow (anchors-protocols §3.1)."""
    if 0x0A <= state <= 0x11:
        return "H"
    if state == 0x14:
        return "I"
    if 0x3C <= state <= 0x3F:
        return "J"
    if 0x32 <= state <= 0x38:
        return "K"
    if 0x1E <= state <= 0x1F:
        return "L"
    if state == MOVING:
        return "M"
    return "D"


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

    Attributes
    ----------
    axis : AxisModel
    state : int
        Controller state code (hex ``ef`` of TS).
    error : str
        Last command error letter (``@`` = none).
    """

    name = "newport-smc100"
    in_terminator = b"\r\n"

    def __init__(self, world, spec: AxisSpec, *, address: int = 1, stage_id: str = "URS100BCC_SIM",
                 version: str = "SMC_CC - Controller-driver version 2.0.0"):
        super().__init__()
        self.world = world
        self.axis = world.new_axis(spec)
        self.address = address
        self.stage_id = stage_id
        self.version = version
        self.state = NOT_REFERENCED_FROM_RESET
        self.error = "@"
        self.target_deg = 0.0

    # -- state ----------------------------------------------------------------------------------------------
    def _refresh(self) -> None:
        """Advance the state machine with the axis: a finished move or homing ends in READY."""
        if self.state in (HOMING, MOVING) and not self.axis.busy():
            self.state = READY_FROM_HOMING if self.state == HOMING else READY_FROM_MOVING

    def error_bits(self) -> int:
        hit = self.axis.limit_hit
        return (1 if hit == "low" else 0) | (2 if hit == "high" else 0)

    def _ready(self) -> bool:
        return 0x32 <= self.state <= 0x38

    def _not_referenced(self) -> bool:
        return 0x0A <= self.state <= 0x11

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
        match = _LINE.match(line.decode("ascii", "replace").strip())
        if not match:
            self.error = "A"
            return b""
        address, command, query, value = int(match[1]), match[2].upper(), match[3], match[4].strip()
        if address != self.address:
            return b""  # not for us
        self._refresh()
        handler = getattr(self, f"_cmd_{command}", None)
        if handler is None:
            self.error = "A"
            return b""
        return handler(query == "?", value)

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

    def _cmd_VA(self, query: bool, value: str) -> bytes:
        if query:
            return self._reply("VA", f"{self.axis.spec.max_rate_deg_s:.6f}")
        rate = self._number(value)
        if rate is None or rate <= 0:
            self.error = "C"
        else:
            self.axis.spec = dataclasses.replace(self.axis.spec, max_rate_deg_s=rate)
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
        return b""
