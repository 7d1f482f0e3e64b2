"""Physical model of one rotation axis on the simulated clock.

Trapezoidal moves (rate and acceleration), settling, backlash, encoder steps, soft limits (refused by the
controller), hard limit switches (motion stops there), homing, and back-door faults (a stalled axis that
still answers, a tripped limit switch). No bytes here: the protocol fronts translate.

Coordinates: the controller reports `position_deg` in its own coordinate, quantised to encoder steps. The
true mechanical angle of the load, which the simulated world uses, is
``load = motor + true_minus_reported − direction × backlash / 2``; homing sets ``true_minus_reported`` so
that the home switch reads `home_position_deg`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .clock import SimClock


@dataclass(frozen=True)
class AxisSpec:
    """Mechanics of one axis.

    Attributes
    ----------
    max_rate_deg_s, accel_deg_s2 : float
        Speed [°/s] and acceleration [°/s²] of moves.
    settle_s : float
        Time after a move before the axis reports it has stopped [s].
    backlash_deg : float
        Play between motor and load [°].
    step_deg : float
        Encoder / micro-step resolution [°].
    soft_limits_deg : (float, float) or None
        Controller limits; a move outside is refused.
    hard_limits_deg : (float, float) or None
        True angles of the limit switches; motion stops there.
    home_switch_true_deg : float
        True angle of the home switch [°] — the table's zero offset.
    home_position_deg : float
        What the controller reads at the home switch after homing [°].
    home_rate_deg_s : float
        Speed of the homing move [°/s].
    start_true_deg : float
        True angle at power-up, when the counter reads 0 [°].
    """

    max_rate_deg_s: float = 10.0
    accel_deg_s2: float = 20.0
    settle_s: float = 0.05
    backlash_deg: float = 0.0
    step_deg: float = 3.0 / 409600.0  # K10CR1: 409600 micro-steps per 3° of worm turn
    soft_limits_deg: tuple[float, float] | None = None
    hard_limits_deg: tuple[float, float] | None = None
    home_switch_true_deg: float = 0.0
    home_position_deg: float = 0.0
    home_rate_deg_s: float = 5.0
    start_true_deg: float = 0.0


class AxisLimitError(Exception):
    """The controller refuses a target outside its soft limits."""


def trapezoid(distance: float, rate: float, accel: float) -> float:
    """Duration of a rest-to-rest move over `distance` with a trapezoidal (or triangular) profile [s]."""
    d = abs(distance)
    if d == 0:
        return 0.0
    if d >= rate * rate / accel:
        return d / rate + rate / accel
    return 2.0 * math.sqrt(d / accel)


def _trapezoid_position(t: float, distance: float, rate: float, accel: float) -> float:
    """Distance covered after `t` seconds of the move (same sign as `distance`)."""
    d, sign = abs(distance), math.copysign(1.0, distance)
    total = trapezoid(d, rate, accel)
    if t >= total:
        return distance
    if d >= rate * rate / accel:
        ta = rate / accel
        if t < ta:
            s = 0.5 * accel * t * t
        elif t < total - ta:
            s = 0.5 * rate * ta + rate * (t - ta)
        else:
            s = d - 0.5 * accel * (total - t) ** 2
    else:
        half = total / 2
        s = 0.5 * accel * t * t if t < half else d - 0.5 * accel * (total - t) ** 2
    return sign * s


class AxisModel:
    """One simulated rotation axis (see the module docstring).

    In instant mode (clock time scale 0) observing the axis completes the move in progress: the clock
    jumps to its end. A stalled axis never completes.
    """

    def __init__(self, spec: AxisSpec, clock: SimClock):
        self.spec = spec
        self.clock = clock
        self.motor_deg = 0.0  # controller coordinate, at the end of the last completed segment
        self.true_minus_reported = spec.start_true_deg
        self.direction = 1.0
        self._homed = False
        self.stalled = False
        self._limit_hit: str | None = None  # "low" / "high"
        self.homing = False
        self._move: tuple[float, float, float, float, float] | None = None  # t0, start, end, rate, duration
        self._frozen_at: float | None = None
        self._limit_on_arrival: str | None = None

    # -- observing ------------------------------------------------------------------------------------
    def _sync(self) -> float:
        now = self.clock.now()
        if self._move and not self.stalled:
            t0, _, _, _, duration = self._move
            done = t0 + duration + self.spec.settle_s
            if self.clock.instant and now < done:
                self.clock.advance_to(done)
                now = done
            if now >= done:
                self._finish()
        return now

    def _finish(self) -> None:
        _, _, end, _, _ = self._move
        self.motor_deg = end
        self._move = None
        if self._limit_on_arrival:
            self._limit_hit, self._limit_on_arrival = self._limit_on_arrival, None
        if self.homing:
            self.homing = False
            self._homed = True
            # the switch now reads home_position_deg
            true = self.motor_deg + self.true_minus_reported
            self.true_minus_reported = true - self.spec.home_position_deg
            self.motor_deg = self.spec.home_position_deg

    def _motor_now(self, now: float) -> float:
        if not self._move:
            return self.motor_deg
        t0, start, end, rate, _ = self._move
        t = (self._frozen_at if self.stalled and self._frozen_at is not None else now) - t0
        return start + _trapezoid_position(max(t, 0.0), end - start, rate, self.spec.accel_deg_s2)

    @property
    def limit_hit(self) -> str | None:
        """The limit switch the axis stands on: "low", "high" or None."""
        self._sync()
        return self._limit_hit

    @property
    def homed(self) -> bool:
        """The homing sequence has completed since power-up."""
        self._sync()
        return self._homed

    def _quantise(self, angle: float) -> float:
        return round(angle / self.spec.step_deg) * self.spec.step_deg

    def position_deg(self) -> float:
        """What the controller reads [°], quantised to encoder steps."""
        return self._quantise(self._motor_now(self._sync()))

    def true_deg(self) -> float:
        """True mechanical angle of the load [°] (the world's truth, not seen by the controller)."""
        motor = self._motor_now(self._sync())
        return motor + self.true_minus_reported - self.direction * self.spec.backlash_deg / 2.0

    def busy(self) -> bool:
        """Moving, homing or settling (a stalled axis stays busy)."""
        self._sync()
        return self._move is not None

    @property
    def moving_direction(self) -> float:
        return self.direction if self.busy() else 0.0

    # -- commanding -------------------------------------------------------------------------------------
    def _start(self, target: float, rate: float) -> float:
        now = self._sync()
        start = self._motor_now(now)
        if self._move:  # a new command supersedes the move (or the homing) in progress, from where the axis is
            self._move = None
        self.homing = False
        self.motor_deg = start
        end = self._quantise(target)
        self._limit_on_arrival = None
        if self.spec.hard_limits_deg is not None:
            low, high = (x - self.true_minus_reported for x in self.spec.hard_limits_deg)
            if end < low or end > high:  # the move will end on the switch, which trips when reached
                self._limit_on_arrival = "low" if end < low else "high"
                end = min(max(end, low), high)
        if end != start:
            self.direction = math.copysign(1.0, end - start)
        duration = trapezoid(end - start, rate, self.spec.accel_deg_s2)
        self._move = (now, start, end, rate, duration)
        self._frozen_at = now if self.stalled else None  # a jammed motor does not turn for a new command
        return duration

    def move_to(self, target_deg: float) -> float:
        """Start a move; returns its duration [s]. Raises :class:`AxisLimitError` outside the soft limits."""
        limits = self.spec.soft_limits_deg
        if limits is not None and not limits[0] <= target_deg <= limits[1]:
            raise AxisLimitError(f"target {target_deg}° outside the soft limits {limits}")
        if self.limit_hit:
            if not self._leaves_limit(target_deg):
                raise AxisLimitError(f"on the {self.limit_hit} limit switch")
            self._limit_hit = None
        return self._start(target_deg, self.spec.max_rate_deg_s)

    def _leaves_limit(self, target_deg: float) -> bool:
        here = self.position_deg()
        return (self.limit_hit == "low" and target_deg > here) or (self.limit_hit == "high" and target_deg < here)

    def move_by(self, delta_deg: float) -> float:
        return self.move_to(self._motor_now(self._sync()) + delta_deg)

    def home(self) -> float:
        """Start homing: move to the home switch at the homing rate; returns the duration [s]."""
        self._limit_hit = None
        switch = self.spec.home_switch_true_deg - self.true_minus_reported
        duration = self._start(switch, self.spec.home_rate_deg_s)
        self.homing = True
        return duration

    def stop(self) -> None:
        """Stop where the axis is (a stalled axis stays where it froze)."""
        now = self._sync()  # a move that ended unobserved has ended (and a homing has re-zeroed)
        if self._move:
            self.motor_deg = self._motor_now(now)
            self._move = None
            self.homing = False
            self._limit_on_arrival = None  # stopped before reaching the switch

    # -- back door --------------------------------------------------------------------------------------
    def stall(self) -> None:
        """The motor stops turning but the controller keeps reporting a move in progress."""
        self.stalled = True
        self._frozen_at = self.clock.now()

    def unstall(self) -> None:
        """Clear a stall: the next command moves again."""
        if self.stalled and self._move:
            self.motor_deg = self._motor_now(self.clock.now())
            self._move = None
            self.homing = False
        self.stalled = False
        self._frozen_at = None

    def trip_limit(self, side: str = "high") -> None:
        """A limit switch closes: motion stops at once."""
        self.stop()
        self._limit_hit = side
