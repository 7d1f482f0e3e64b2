"""The back door of a whole simulated bench: faults no wire protocol can cause, and named set-ups of them.

A test or a demo reaches the bench's truth through :attr:`drivers.sim.bench.SimBench.faults` (a
:class:`BenchFaults`) instead of the world's internals; each device's link faults stay on its own
``faults`` (:class:`drivers.sim.device.WireFaults`). A *set-up* is a named scenario
(:data:`SETUPS`, :meth:`BenchFaults.setup`), the way lewis names its device scenarios.
"""

from __future__ import annotations

from .world import SimWorld

#: Sensor temperature of the ``hot_sensor`` set-up [°C]: above the default 60 °C interlock.
HOT_SENSOR_C = 75.0


class BenchFaults:
    """Faults of one simulated bench, set and cleared by name.

    Parameters
    ----------
    world : SimWorld
        The bench's shared truth.
    normal_temperature_c : float
        The sensor's temperature without a fault [°C] (the bench's configured one).
    earth : EarthSimulatorModel, optional
        The IR Earth simulator of a horizon bench: its heater is the bench's "lamp" (the source the engine lights).
    """

    def __init__(self, world: SimWorld, *, normal_temperature_c: float, earth=None):
        self._world = world
        self._normal_temperature_c = normal_temperature_c
        self._earth = earth

    # -- the enclosure ----------------------------------------------------------------------------------
    def open_enclosure(self) -> None:
        """The enclosure's door opens (its switch reads open)."""
        self._world.enclosure_open = True

    def close_enclosure(self) -> None:
        self._world.enclosure_open = False

    # -- the lamp ---------------------------------------------------------------------------------------
    def lamp_fault(self) -> None:
        """The arc (or the LED string) goes out and the supply flags a fault; on a horizon bench the Earth simulator's
        heater trips."""
        if self._earth is not None:
            self._earth.heater_fault()
        else:
            self._world.lamp.inject_fault()

    def clear_lamp_fault(self) -> None:
        if self._earth is not None:
            self._earth.clear_faults()
        self._world.lamp.clear_fault()

    def open_lamp_interlock(self) -> None:
        """The supply's interlock opens: it refuses to strike and puts a burning lamp out."""
        self._world.lamp.interlock_open = True

    def close_lamp_interlock(self) -> None:
        self._world.lamp.interlock_open = False

    # -- the sensor and the table -----------------------------------------------------------------------
    def sensor_temperature(self, temperature_c: float) -> None:
        """Set the sensor module's temperature [°C] (what it reports and its dark current follow)."""
        self._world.temperature_c = float(temperature_c)

    def stall(self, axis: str) -> None:
        """The `axis` ("azimuth" or "zenith") motor stops turning while its controller reports a move."""
        self._axis(axis).stall()

    def unstall(self, axis: str) -> None:
        self._axis(axis).unstall()

    def _axis(self, name: str):
        if name not in ("azimuth", "zenith"):
            raise ValueError(f"`axis` must be 'azimuth' or 'zenith', got {name!r}")
        axis = getattr(self._world, name)
        if axis is None:
            raise ValueError(f"the bench has no {name} axis attached")
        return axis

    # -- named set-ups ----------------------------------------------------------------------------------
    def setup(self, name: str) -> None:
        """Put the bench in the named set-up (:data:`SETUPS`); ``"normal"`` clears every fault."""
        if name not in SETUPS:
            raise ValueError(f"unknown set-up {name!r}; known: {sorted(SETUPS)}")
        SETUPS[name](self)

    def clear(self) -> None:
        """Every fault cleared: door closed, lamp healthy, sensor at its configured temperature, axes free."""
        self.close_enclosure()
        self.clear_lamp_fault()
        self.close_lamp_interlock()
        self.sensor_temperature(self._normal_temperature_c)
        for name in ("azimuth", "zenith"):
            if getattr(self._world, name) is not None:
                self.unstall(name)


#: Named set-ups of a simulated bench: name → what it does to the :class:`BenchFaults`.
SETUPS = {
    "normal": BenchFaults.clear,
    "enclosure_open": BenchFaults.open_enclosure,
    "lamp_fault": BenchFaults.lamp_fault,
    "lamp_interlock_open": BenchFaults.open_lamp_interlock,
    "hot_sensor": lambda faults: faults.sensor_temperature(HOT_SENSOR_C),
    "stalled_azimuth": lambda faults: faults.stall("azimuth"),
    "stalled_zenith": lambda faults: faults.stall("zenith"),
}
