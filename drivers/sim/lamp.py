"""Physical model of the sun simulator's source: a xenon arc lamp or an LED, and a shutter.

A xenon lamp ignites after a short delay, then its output climbs toward its final value with a warm-up
time constant and drifts slowly; an LED is on at once. The shutter passes or blocks the beam. Back-door
faults: a lamp fault (the arc goes out, the supply flags it) and an open interlock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .clock import SimClock


@dataclass(frozen=True)
class LampSpec:
    """Behaviour of a source.

    Attributes
    ----------
    kind : str
        "xenon" or "led".
    ignition_s : float
        Delay from START to light [s].
    warmup_tau_s : float
        Time constant of the warm-up [s]; the lamp counts as warm within `warm_tolerance` of its final output.
    warm_tolerance : float
        Relative output error that counts as warm.
    drift_per_hour : float
        Relative amplitude of the slow output drift once warm.
    nominal_current_a : float
        Operating current of the lamp [A] (xenon 69907 presets are a few amperes; an LED string less).
    """

    kind: str = "xenon"
    ignition_s: float = 2.0
    warmup_tau_s: float = 120.0
    warm_tolerance: float = 0.01
    drift_per_hour: float = 0.005
    nominal_current_a: float = 5.0


    @property
    def warm_time_s(self) -> float:
        """Time from START until the output is within `warm_tolerance` of its final value [s]."""
        return self.ignition_s + self.warmup_tau_s * math.log(0.3 / self.warm_tolerance)


XENON = LampSpec()
LED = LampSpec(kind="led", ignition_s=0.0, warmup_tau_s=0.5, warm_tolerance=0.01, drift_per_hour=0.001,
               nominal_current_a=0.7)


class LampModel:
    """A lamp with its shutter on the simulated clock. In instant mode, asking whether it is warm completes
    the warm-up."""

    def __init__(self, spec: LampSpec, clock: SimClock):
        self.spec = spec
        self.clock = clock
        self.on = False
        self.t_on = 0.0
        self.current_a = spec.nominal_current_a
        self.shutter_open = False
        self.fault = False
        self.interlock_open = False
        self.hours = 0.0

    def start(self) -> None:
        if self.fault or self.interlock_open:
            return  # a supply refuses to strike with a fault or an open interlock
        if not self.on:
            self.on = True
            self.t_on = self.clock.now()

    def stop(self) -> None:
        if self.on:
            self.hours += max(self.clock.now() - self.t_on, 0.0) / 3600.0
        self.on = False

    def relative_output(self) -> float:
        """Light output as a fraction of the warm, nominal output [unitless]."""
        if not self.on or self.fault:
            return 0.0
        t = self.clock.now() - self.t_on - self.spec.ignition_s
        if t < 0:
            return 0.0
        scale = self.current_a / self.spec.nominal_current_a
        warm = 1.0 - 0.3 * math.exp(-t / self.spec.warmup_tau_s)
        drift = 1.0 + self.spec.drift_per_hour * math.sin(2 * math.pi * t / 3600.0)
        return scale * warm * drift

    def warm_at(self) -> float:
        """Simulated time at which the lamp counts as warm [s]."""
        return self.t_on + self.spec.warm_time_s

    def is_warm(self) -> bool:
        if not self.on or self.fault:
            return False
        if self.clock.instant:
            self.clock.advance_to(self.warm_at())
        return self.clock.now() >= self.warm_at()

    def irradiance(self) -> float:
        """Relative irradiance at the sensor: output through the shutter [unitless]."""
        return self.relative_output() if self.shutter_open else 0.0

    # -- back door --------------------------------------------------------------------------------------
    def inject_fault(self) -> None:
        """The arc goes out and the supply flags a fault."""
        self.fault = True
        self.stop()

    def clear_fault(self) -> None:
        self.fault = False
