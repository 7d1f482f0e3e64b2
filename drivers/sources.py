"""The two sun simulators of the bench, as :class:`~drivers.interfaces.SunSimulator`:

* :class:`ArcLampSource` — a xenon arc lamp (seed 002) on an Oriel 69907 supply, behind a Thorlabs SC10
  shutter (the 69907 has no shutter command, anchors-protocols §4.1);
* :class:`LedSource` — an LED string on a SCPI bench supply (anchors-protocols §4.2), whose output is its
  shutter: an LED with its output off is dark, so it needs no mechanical shutter.

Warm-up. Neither supply reports how warm its source is. The 69907 reports "lamp on" (STB bit 7); the
source counts the lamp warm once it has been on for `warmup_s`, timed from the ``START`` command on the
supply driver's clock (:attr:`Oriel69907.started_at_s`). The LED is timed the same way from ``OUTP ON``.
On a simulated bench the drivers get the simulation's clock, so warm-up runs in simulated time.

Standby. Between runs the arc lamp keeps burning at its preset with the shutter closed: a xenon lamp is not
re-struck between runs, because every ignition wears the electrodes and starts the warm-up over. The LED
source just switches its output off (it is warm again within seconds). When the shutter cannot be closed, the
run engine puts the light out with :meth:`~drivers.interfaces.SunSimulator.lamp_off` instead (the arc re-struck
later, with its warm-up).
"""

from __future__ import annotations

import logging
import math

from .errors import DeviceFault, LimitError
from .interfaces import SourceStatus, SunSimulator
from .oriel69907 import Oriel69907
from .scpi_supply import ScpiSupply
from .shutter import ThorlabsSC10

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

# Warm-up defaults [s]: bench choices, not vendor figures. A xenon arc is usually left 20–30 min before
# measurements; an LED's junction settles within about a minute. A simulated bench passes the warm-up time
# of its lamp model instead.
ARC_WARMUP_S = 1800.0
LED_WARMUP_S = 60.0
# Slack of the warm-up comparison [s]: a simulated clock jumps exactly to the model's warm time, and float
# rounding of (start + warm-up) - start must not keep a lamp cold for ever. Far below any real timing.
_CLOCK_SLACK_S = 1e-6


class ArcLampSource(SunSimulator):
    """Xenon arc lamp on an Oriel 69907 supply, behind a Thorlabs SC10 shutter.

    Parameters
    ----------
    supply : Oriel69907
    shutter : ThorlabsSC10
        Put in manual mode by the caller (:meth:`ThorlabsSC10.configure`) before use.
    current_a : float, optional
        Current preset set at :meth:`lamp_on` [A]; None keeps the supply's preset. Checked against the
        supply's limit at construction, so a bad value is refused before anything is sent.
    warmup_s : float
        Time after ``START`` after which the lamp counts as warm [s].
    name : str
    """

    def __init__(self, supply: Oriel69907, shutter: ThorlabsSC10, *, current_a: float | None = None,
                 warmup_s: float = ARC_WARMUP_S, name: str = "arc-lamp"):
        if current_a is not None and not (math.isfinite(current_a) and 0.0 < current_a <= supply.max_current_a):
            raise LimitError(name, f"lamp current {current_a} A is outside (0, {supply.max_current_a}] A")
        self.supply = supply
        self.shutter = shutter
        self.current_a = current_a
        self.warmup_s = float(warmup_s)
        self.name = name

    def identify(self) -> str:
        return f"supply: {self.supply.identify()}; shutter: {self.shutter.identify()}"

    def lamp_on(self) -> None:
        """Strike the lamp unless it burns already; a fault or an open interlock raises DeviceFault first."""
        stb = self.supply.status_byte()
        if stb.fault or stb.interlock_open:
            why = "lamp fault" if stb.fault else "interlock open"
            raise DeviceFault(self.name, f"cannot start the lamp: {why} (STB {stb.value:02X})")
        if self.current_a is not None:
            self.supply.set_current_preset_a(self.current_a)
        if not stb.lamp_on:
            self.supply.start()

    def lamp_off(self) -> None:
        """Stop the lamp (``STOP``), then close the shutter if it answers: the end of the day, and the fallback
        when the shutter cannot be closed (so a shutter that fails is logged, not raised: the lamp is out)."""
        self.supply.stop()
        try:
            self.close_shutter()
        except Exception as exc:  # noqa: BLE001 - see the docstring
            log.warning("%s: lamp stopped, but the shutter did not close: %s", self.name, exc)

    def standby(self) -> None:
        """Close the shutter; the lamp keeps burning at its preset (see the module docstring)."""
        self.close_shutter()

    def open_shutter(self) -> None:
        """Open the SC10 shutter and check it opened (a tripped shutter interlock raises DeviceFault)."""
        self.shutter.open()

    def close_shutter(self) -> None:
        """Close the SC10 shutter and check it closed."""
        self.shutter.close()

    def status(self) -> SourceStatus:
        """Lamp state from the 69907 status byte and current, shutter state from ``closed?``.

        ``warm`` = lamp on, no fault, and on for at least `warmup_s` since START on the supply driver's clock.
        ``fault`` = STB fault bit or open interlock. ``output`` is the lamp current [A].
        """
        stb = self.supply.status_byte()
        fault = stb.fault or stb.interlock_open
        started = self.supply.started_at_s
        warm = (stb.lamp_on and not fault and started is not None
                and self.supply.clock() - started >= self.warmup_s - _CLOCK_SLACK_S)
        amps = self.supply.amps()
        return SourceStatus(lamp_on=stb.lamp_on, warm=warm, shutter_open=self.shutter.is_open(), fault=fault,
                            output=amps, output_unit="A")


class LedSource(SunSimulator):
    """LED string on a SCPI bench supply in constant-current mode; the output is the shutter.

    :meth:`lamp_on` and :meth:`open_shutter` both set the current and switch the output on (an LED only warms
    up while it shines); :meth:`close_shutter` and :meth:`standby` switch it off.

    Parameters
    ----------
    supply : ScpiSupply
    current_a : float
        LED drive current [A]; checked against the supply's limit here, before anything is sent.
    voltage_v : float, optional
        Compliance voltage [V] sent with the current (``APPL``); None sends ``CURR`` only.
    warmup_s : float
        Time after ``OUTP ON`` after which the LED counts as warm [s].
    fault_fraction : float
        With the output on, a measured current below this fraction of `current_a` is an open LED string
        (the supply runs into its voltage compliance) and counts as a fault.
    name : str
    """

    def __init__(self, supply: ScpiSupply, current_a: float, *, voltage_v: float | None = None,
                 warmup_s: float = LED_WARMUP_S, fault_fraction: float = 0.5, name: str = "led"):
        if not (math.isfinite(current_a) and 0.0 < current_a <= supply.max_current_a):
            raise LimitError(name, f"LED current {current_a} A is outside (0, {supply.max_current_a}] A")
        if voltage_v is not None and not (math.isfinite(voltage_v) and 0.0 < voltage_v <= supply.max_voltage_v):
            raise LimitError(name, f"compliance voltage {voltage_v} V is outside (0, {supply.max_voltage_v}] V")
        self.supply = supply
        self.current_a = float(current_a)
        self.voltage_v = voltage_v
        self.warmup_s = float(warmup_s)
        self.fault_fraction = float(fault_fraction)
        self.name = name

    def identify(self) -> str:
        return f"supply: {self.supply.identify()}"

    def lamp_on(self) -> None:
        """Set the LED current and switch the output on (the LED lights: it has no shutter)."""
        if self.voltage_v is None:
            self.supply.set_current_a(self.current_a)
        else:
            self.supply.apply(self.voltage_v, self.current_a)
        self.supply.set_output(True)

    def standby(self) -> None:
        """Switch the output off: the LED is dark."""
        self.supply.set_output(False)

    def lamp_off(self) -> None:
        """Switch the output off (the LED has no shutter but its output)."""
        self.supply.set_output(False)

    def open_shutter(self) -> None:
        """Same as :meth:`lamp_on`: the output is the LED's shutter."""
        self.lamp_on()

    def close_shutter(self) -> None:
        """Switch the output off."""
        self.supply.set_output(False)

    def status(self) -> SourceStatus:
        """``lamp_on`` = ``shutter_open`` = output on; ``fault`` = output on but (almost) no current flows;
        ``warm`` = on for `warmup_s` since OUTP ON on the supply driver's clock; ``output`` the current [A]."""
        on = self.supply.output_enabled()
        amps = self.supply.measure_current_a()
        fault = on and amps < self.fault_fraction * self.current_a
        started = self.supply.output_on_at_s
        warm = (on and not fault and started is not None
                and self.supply.clock() - started >= self.warmup_s - _CLOCK_SLACK_S)
        return SourceStatus(lamp_on=on, warm=warm, shutter_open=on, fault=fault, output=amps, output_unit="A")
