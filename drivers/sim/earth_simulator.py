"""The simulated IR Earth simulator: its model (a heated disc, an iris, a cold cover on the simulated clock) and its
protocol front, a SCPI-style line protocol (the driver is :mod:`drivers.earth_simulator`).

**The instrument.** A warm spherical cap (the "Earth") behind an adjustable iris that sets its angular radius ρ seen
from the sensor's nominal point, on a cold background (a cooled shroud), with a cold cover that slides in front of
it (the bench's shutter). A heater regulates the disc's temperature: first order towards the setpoint with the time
constant `thermal_tau_s` (heater off: towards the room); it counts as settled within `settle_tolerance_k` of the
setpoint. The iris moves at `iris_speed_deg_s` and settles for `iris_settle_s`; the cover takes `cover_s` to open or
close (while it moves the disc counts as covered). In instant mode (clock time scale 0) observing a motion or the
heater over the wire completes it, as observing an axis completes its move.

**Wire.** Program messages end with LF (a CR before it is ignored), one or more message units separated by ``;``
(each from the root); a query's answer ends with LF. Mnemonics are case-insensitive, in their short (upper-case
part) or long form; nodes in brackets are optional::

    *IDN?                              SUNBENCH,EARTH-SIM,<serial>,1.0
    *RST                               heater off, setpoint to its power-up value, cover closed (the iris stays)
    *CLS                               empties the error queue
    SYSTem:ERRor[:NEXT]?               <code>,"<text>" (0,"No error" when empty)
    HEATer[:STATe] ON|OFF|1|0          heater on / off; ON with a heater fault is refused (−221)
    HEATer[:STATe]?                    1 | 0
    HEATer:TEMPerature <K>             the disc's setpoint [K] (−222 outside the heater's range)
    HEATer:TEMPerature?                the setpoint [K]
    HEATer:RANGe?                      <low>,<high> [K]
    MEASure:TEMPerature?               the disc's measured temperature [K]
    MEASure:BACKground?                the background's temperature [K]
    IRIS[:RADius] <deg>                move the iris to an angular radius [°] (−222 outside its limits)
    IRIS[:RADius]?                     the iris's position [°]
    IRIS:TARGet?                       its target [°]
    IRIS:SPEed?                        its speed [°/s]
    IRIS:LIMits?                       <low>,<high> [°]
    IRIS:MOVing?                       1 while it moves or settles, else 0
    IRIS:STOP                          stop the iris where it is: its target becomes its position (MOVing? 1 while
                                       it settles, iris_settle_s); an iris whose drive slips stops reporting a move
    COVer[:STATe] OPEN|CLOSe           open / close the cold cover
    COVer[:STATe]?                     OPEN | CLOSED | MOVING
    STATus?                            status word: bit 0 heater on, 1 disc settled, 2 iris moving, 3 cover open,
                                       4 cover moving, 5 heater fault; bits 6-7 reserved (0)

Errors go on a queue (20 entries, the last replaced by −350 when full): −102 syntax, −104 data type, −108 parameter
not allowed, −109 missing parameter, −113 undefined header, −221 settings conflict, −222 data out of range.

**Back door** (never on the wire): :meth:`EarthSimulatorModel.heater_fault` (the heater trips: off, fault bit, the
disc drifts to the room), :meth:`~EarthSimulatorModel.stick_iris` (the iris stops where it is and never arrives:
the controller keeps reporting a move; its fault bit stays clear, as a slipping drive's would),
:meth:`~EarthSimulatorModel.stick_cover` (the cover stays where it is), :meth:`~EarthSimulatorModel.clear_faults`,
and the :class:`~drivers.sim.device.WireFaults` of every simulator.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from .clock import SimClock
from .device import LineDevice

FIRMWARE = "1.0"
KELVIN = 273.15

ERRORS = {-102: "Syntax error", -104: "Data type error", -108: "Parameter not allowed", -109: "Missing parameter",
          -113: "Undefined header", -221: "Settings conflict", -222: "Data out of range", -350: "Queue overflow"}
QUEUE_SIZE = 20

STATUS_HEATER, STATUS_SETTLED, STATUS_IRIS_MOVING, STATUS_COVER_OPEN = 0x01, 0x02, 0x04, 0x08
STATUS_COVER_MOVING, STATUS_HEATER_FAULT = 0x10, 0x20


class EarthSimulatorConfig(BaseModel):
    """The simulated Earth simulator (the ``simulation.earth`` section of a bench file)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    serial: str = "ES-0001"
    iris_range_deg: tuple[float, float] = (45.0, 80.0)  # the iris's mechanical limits [°]
    iris_start_deg: float = 68.0  # where it stands at power-up [°]
    iris_speed_deg_s: float = Field(0.5, gt=0)
    iris_settle_s: float = Field(0.5, ge=0)
    iris_offset_deg: float = 0.0  # the true radius minus the reported one [°]: the iris scale's error
    heater_range_k: tuple[float, float] = (230.0, 350.0)  # setpoints the heater accepts [K]
    setpoint_k: float = 290.0  # the power-up setpoint [K]
    thermal_tau_s: float = Field(120.0, gt=0)  # the disc's thermal time constant [s]
    settle_tolerance_k: float = Field(0.5, gt=0)
    background_k: float = Field(120.0, gt=0)  # the cooled shroud (and the closed cover) [K]
    cover_s: float = Field(1.0, ge=0)  # the cover's travel time [s]
    thermometer_noise_k: float = Field(0.02, ge=0)

    @model_validator(mode="after")
    def _consistent(self):
        for name in ("iris_range_deg", "heater_range_k"):
            low, high = getattr(self, name)
            if not low < high:
                raise ValueError(f"`{name}` must satisfy low < high, got [{low}, {high}]")
        low, high = self.iris_range_deg
        if not (0 < low and high < 90):
            raise ValueError(f"`iris_range_deg` must lie within (0, 90)°, got [{low}, {high}]")
        if not low <= self.iris_start_deg <= high:
            raise ValueError(f"`iris_start_deg` {self.iris_start_deg} is outside `iris_range_deg` [{low}, {high}]")
        low, high = self.heater_range_k
        if not low <= self.setpoint_k <= high:
            raise ValueError(f"`setpoint_k` {self.setpoint_k} is outside `heater_range_k` [{low}, {high}]")
        return self

    def settle_time_s(self, step_k: float) -> float:
        """Time for the disc to settle after a setpoint step of `step_k` [K] [s]."""
        return self.thermal_tau_s * math.log(max(abs(step_k) / self.settle_tolerance_k, 1.0))


class EarthSimulatorModel:
    """The Earth simulator's state on the simulated clock (module docstring).

    Parameters
    ----------
    config : EarthSimulatorConfig
    clock : SimClock
    room_k : callable
        The room's temperature now [K] (where the disc drifts with the heater off).
    """

    def __init__(self, config: EarthSimulatorConfig, clock: SimClock, room_k: Callable[[], float]):
        self.config, self.clock, self.room_k = config, clock, room_k
        now = clock.now()
        self.heater_on = False
        self.setpoint_k = config.setpoint_k
        self._t0, self._disc0 = now, room_k()  # the disc's last change of target: when, and its temperature then
        # at rest at power-up: its last move (none) ended a settling time ago
        self._iris_t0, self._iris_from, self._iris_to = now - config.iris_settle_s, config.iris_start_deg, \
            config.iris_start_deg
        self._cover_t0, self._cover_open_target = now - config.cover_s, False
        self.heater_faulted = self.iris_stuck = self.cover_stuck = False

    # -- heater ---------------------------------------------------------------------------------------------
    def _target_k(self) -> float:
        return self.setpoint_k if self.heater_on else self.room_k()

    def disc_k(self, t: float | None = None) -> float:
        """The disc's true temperature [K] at `t` (default now)."""
        t = self.clock.now() if t is None else t
        target = self._target_k()
        return target + (self._disc0 - target) * math.exp(-max(t - self._t0, 0.0) / self.config.thermal_tau_s)

    def _retarget(self) -> None:
        now = self.clock.now()
        self._disc0, self._t0 = self.disc_k(now), now

    def set_heater(self, on: bool) -> bool:
        """Switch the heater; refused (False) when switching on with a heater fault."""
        if on and self.heater_faulted:
            return False
        self._retarget()
        self.heater_on = bool(on)
        return True

    def set_setpoint(self, kelvin: float) -> None:
        self._retarget()
        self.setpoint_k = float(kelvin)

    def settled(self) -> bool:
        return self.heater_on and abs(self.disc_k() - self.setpoint_k) <= self.config.settle_tolerance_k

    def observe_heater(self) -> None:
        """In instant mode, being asked completes the settling (the clock jumps to the moment it has settled)."""
        if self.clock.instant and self.heater_on and not self.settled():
            self.clock.advance_to(self._t0 + self.config.settle_time_s(self._disc0 - self.setpoint_k) + 1e-6)

    # -- iris -----------------------------------------------------------------------------------------------
    def _iris_done_s(self) -> float:
        return (self._iris_t0 + abs(self._iris_to - self._iris_from) / self.config.iris_speed_deg_s
                + self.config.iris_settle_s)

    def iris_deg(self, t: float | None = None) -> float:
        """The iris's position (what its encoder reads) [°]."""
        t = self.clock.now() if t is None else t
        if self.iris_stuck:
            return self._iris_from
        travelled = max(t - self._iris_t0, 0.0) * self.config.iris_speed_deg_s
        span = self._iris_to - self._iris_from
        return self._iris_to if travelled >= abs(span) else self._iris_from + math.copysign(travelled, span)

    def true_radius_deg(self) -> float:
        """The disc's true angular radius [°]: the iris's position and its scale's error."""
        return self.iris_deg() + self.config.iris_offset_deg

    @property
    def iris_target_deg(self) -> float:
        return self._iris_to

    def move_iris(self, radius_deg: float) -> None:
        now = self.clock.now()
        self._iris_from, self._iris_to, self._iris_t0 = self.iris_deg(now), float(radius_deg), now

    def stop_iris(self) -> None:
        """Stop where it is: the target becomes the position, then it settles (``IRIS:STOP``)."""
        now = self.clock.now()
        here = self.iris_deg(now)
        self._iris_from, self._iris_to, self._iris_t0 = here, here, now

    def iris_moving(self) -> bool:
        # a slipping drive: the controller reports a move for as long as it has somewhere to go
        return self.iris_stuck and self._iris_to != self._iris_from or self.clock.now() < self._iris_done_s()

    def observe_iris(self) -> None:
        if self.clock.instant and not self.iris_stuck:
            self.clock.advance_to(self._iris_done_s())

    # -- cover ----------------------------------------------------------------------------------------------
    def move_cover(self, open_: bool) -> None:
        if self.cover_stuck or open_ == self._cover_open_target:
            return
        now = self.clock.now()
        done = self._cover_t0 + self.config.cover_s
        # reversing a cover in travel takes as long back as it had come
        self._cover_t0 = now - max(done - now, 0.0) if now < done else now
        self._cover_open_target = bool(open_)

    def cover_moving(self) -> bool:
        return self.clock.now() < self._cover_t0 + self.config.cover_s

    def cover_open(self) -> bool:
        """The cover is fully open (the disc in view)."""
        return self._cover_open_target and not self.cover_moving()

    def cover_state(self) -> str:
        if self.cover_moving():
            return "MOVING"
        return "OPEN" if self._cover_open_target else "CLOSED"

    def observe_cover(self) -> None:
        if self.clock.instant:
            self.clock.advance_to(self._cover_t0 + self.config.cover_s)

    # -- back door ------------------------------------------------------------------------------------------
    def heater_fault(self) -> None:
        """The heater trips: it switches off and flags a fault until cleared."""
        self._retarget()
        self.heater_on, self.heater_faulted = False, True

    def stick_iris(self) -> None:
        """The iris stops where it is; the controller keeps reporting a move that never ends (until told to stop)."""
        self._iris_from = self.iris_deg()
        self.iris_stuck = True

    def stick_cover(self) -> None:
        """The cover no longer moves when told to (a travel under way finishes)."""
        self.cover_stuck = True

    def clear_faults(self) -> None:
        if self.iris_stuck:
            self.iris_stuck = False
            self._iris_t0 = self.clock.now()  # the move resumes from where it stuck
        self.heater_faulted = self.cover_stuck = False

    def status_word(self) -> int:
        bits = [(self.heater_on, STATUS_HEATER), (self.settled(), STATUS_SETTLED),
                (self.iris_moving(), STATUS_IRIS_MOVING), (self.cover_open(), STATUS_COVER_OPEN),
                (self.cover_moving(), STATUS_COVER_MOVING), (self.heater_faulted, STATUS_HEATER_FAULT)]
        return sum(bit for on, bit in bits if on)


# -- the protocol front -------------------------------------------------------------------------------------
class _Error(Exception):
    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


def _nodes(pattern: str) -> list[tuple[str, str, bool]]:
    """``HEATer[:STATe]`` → [(short, long, optional)] of each node, upper case."""
    return [("".join(c for c in name if c.isupper() or c == "*"), name.upper(), bool(optional))
            for optional, name in re.findall(r"(\[?):?([A-Za-z*]+)\]?", pattern)]


def _matches(parts: list[str], nodes: list[tuple[str, str, bool]]) -> bool:
    """The header's nodes `parts` spell the pattern `nodes` (short or long forms, optional nodes left out)."""
    if not nodes:
        return not parts
    short, long, optional = nodes[0]
    if optional and _matches(parts, nodes[1:]):
        return True
    return bool(parts) and parts[0].upper() in (short, long) and _matches(parts[1:], nodes[1:])


class EarthSimulatorSimulator(LineDevice):
    """The Earth simulator's controller on the simulated bench (module docstring).

    Parameters
    ----------
    model : EarthSimulatorModel
        The instrument (shared with the horizon sensor's simulator, which looks at it).
    seed : int
        Seed of the thermometer's noise.
    """

    name = "earth-simulator"
    in_terminator = b"\n"

    def __init__(self, model: EarthSimulatorModel, *, seed: int = 0):
        super().__init__()
        self.model = model
        self.errors: list[int] = []
        self._noise = np.random.default_rng([seed, 0xEA27])
        m = model
        queries: dict[str, Callable[[], str]] = {
            "*IDN": self._idn, "SYSTem:ERRor[:NEXT]": self._err,
            "HEATer[:STATe]": lambda: "1" if m.heater_on else "0",
            "HEATer:TEMPerature": lambda: f"{m.setpoint_k:.3f}",
            "HEATer:RANGe": lambda: "{:.3f},{:.3f}".format(*m.config.heater_range_k),
            "MEASure:TEMPerature": self._measure, "MEASure:BACKground": lambda: f"{m.config.background_k:.3f}",
            "IRIS[:RADius]": lambda: f"{m.iris_deg():.4f}", "IRIS:TARGet": lambda: f"{m.iris_target_deg:.4f}",
            "IRIS:SPEed": lambda: f"{m.config.iris_speed_deg_s:.4f}",
            "IRIS:LIMits": lambda: "{:.4f},{:.4f}".format(*m.config.iris_range_deg),
            "IRIS:MOVing": self._iris_moving, "COVer[:STATe]": self._cover_state, "STATus": self._status}
        sets: dict[str, Callable[[str], None]] = {
            "*RST": self._rst, "*CLS": self._cls, "HEATer[:STATe]": self._heater, "HEATer:TEMPerature": self._setpoint,
            "IRIS[:RADius]": self._iris, "IRIS:STOP": self._iris_stop, "COVer[:STATe]": self._cover}
        self._queries = [(_nodes(p), h) for p, h in queries.items()]
        self._sets = [(_nodes(p), h) for p, h in sets.items()]

    # -- framing --------------------------------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes:
        text = line.decode("ascii", "replace").strip()
        answers = []
        for unit in (u.strip() for u in text.split(";")):
            if not unit:
                continue
            try:
                answer = self._execute(unit)
            except _Error as exc:
                self._push(exc.code)
                continue
            if answer is not None:
                answers.append(answer)
        return (";".join(answers) + "\n").encode("ascii") if answers else b""

    def _push(self, code: int) -> None:
        if len(self.errors) >= QUEUE_SIZE:
            self.errors[-1] = -350
        else:
            self.errors.append(code)

    def _execute(self, unit: str) -> str | None:
        header, _, argument = unit.partition(" ")
        argument = argument.strip()
        if not re.fullmatch(r":?[A-Za-z*][A-Za-z:]*\??", header):
            raise _Error(-102)
        query = header.endswith("?")
        parts = header.rstrip("?").lstrip(":").split(":")
        for nodes, handler in self._queries if query else self._sets:
            if _matches(parts, nodes):
                if query:
                    if argument:
                        raise _Error(-108)
                    return handler()
                handler(argument)
                return None
        raise _Error(-113)

    @staticmethod
    def _number(argument: str) -> float:
        if not argument:
            raise _Error(-109)
        try:
            value = float(argument)
        except ValueError:
            raise _Error(-104) from None
        if not math.isfinite(value):
            raise _Error(-104)
        return value

    @staticmethod
    def _nothing(argument: str) -> None:
        if argument:
            raise _Error(-108)

    # -- commands -------------------------------------------------------------------------------------------
    def _idn(self) -> str:
        return f"SUNBENCH,EARTH-SIM,{self.model.config.serial},{FIRMWARE}"

    def _rst(self, argument: str) -> None:
        self._nothing(argument)
        self.model.set_heater(False)
        self.model.set_setpoint(self.model.config.setpoint_k)
        self.model.move_cover(False)

    def _cls(self, argument: str) -> None:
        self._nothing(argument)
        self.errors.clear()

    def _err(self) -> str:
        if not self.errors:
            return '0,"No error"'
        code = self.errors.pop(0)
        return f'{code},"{ERRORS[code]}"'

    def _heater(self, argument: str) -> None:
        word = argument.upper()
        if not word:
            raise _Error(-109)
        if word not in ("ON", "OFF", "1", "0"):
            raise _Error(-104)
        if not self.model.set_heater(word in ("ON", "1")):
            raise _Error(-221)

    def _setpoint(self, argument: str) -> None:
        kelvin = self._number(argument)
        low, high = self.model.config.heater_range_k
        if not low <= kelvin <= high:
            raise _Error(-222)
        self.model.set_setpoint(kelvin)

    def _measure(self) -> str:
        self.model.observe_heater()
        noise = self.model.config.thermometer_noise_k * self._noise.standard_normal()
        return f"{self.model.disc_k() + noise:.3f}"

    def _iris(self, argument: str) -> None:
        radius = self._number(argument)
        low, high = self.model.config.iris_range_deg
        if not low <= radius <= high:
            raise _Error(-222)
        self.model.move_iris(radius)

    def _iris_stop(self, argument: str) -> None:
        self._nothing(argument)
        self.model.stop_iris()

    def _iris_moving(self) -> str:
        self.model.observe_iris()
        return "1" if self.model.iris_moving() else "0"

    def _cover(self, argument: str) -> None:
        word = argument.upper()
        if not word:
            raise _Error(-109)
        if word == "OPEN":
            self.model.move_cover(True)
        elif word in ("CLOS", "CLOSE"):
            self.model.move_cover(False)
        else:
            raise _Error(-104)

    def _cover_state(self) -> str:
        self.model.observe_cover()
        return self.model.cover_state()

    def _status(self) -> str:
        self.model.observe_heater()
        self.model.observe_iris()
        self.model.observe_cover()
        return str(self.model.status_word())
