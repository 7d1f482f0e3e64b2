"""A simulated field: the sensor under test outdoors, on a mount, under the real Sun and passing clouds.

The world of a field run is a :class:`~drivers.sim.world.SimWorld` whose light comes from the sky instead of the
bench: the Sun's direction in the sensor's body frame follows :class:`~drivers.sim.sky.SimulatedSky` (SPA's
airless ephemeris and this simulator's refraction) through the mount's true heading and tilt
(:class:`~drivers.sim.sky.SimulatedMount`), its brightness through haze and clouds, and a cloud's edge across the
disc reaches the spot's shape (:func:`drivers.sim.raytrace.spot_patch`'s occlusion). The sensor simulators are
the bench's own (the CMOS module: :class:`~drivers.sim.cmos_sensor.CmosSensorSimulator`), served at a
``sim://`` URL, so a field run goes through the same driver and wire protocol as a bench run.

The simulated clock's zero is `start_utc_s`: a reading at clock time t was taken at UTC start + t.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .sky import SUN_DIAMETER_DEG, CloudState, SimulatedMount, SimulatedSky
from .world import SimWorld

#: The real Sun's irradiance on a CMOS module relative to the bench lamp's at 1.0: a clear Sun at normal
#: incidence fills the simulated module at about 0.6 ms (the field's exposure is set per reading).
SUN_IRRADIANCE = 8.0


@dataclass
class FieldWorld(SimWorld):
    """The shared truth of a field run (see the module docstring).

    Attributes
    ----------
    sky : SimulatedSky
    field_mount : SimulatedMount
        The sensor's true attitude.
    start_utc_s : float
        UTC of the clock's zero (Unix seconds).
    sun_irradiance : float
        The clear Sun at the sensor, relative to the bench lamp [unitless].
    """

    sky: SimulatedSky = field(default_factory=lambda: SimulatedSky(49.3052028, 14.1633511, 378.0))
    field_mount: SimulatedMount = field(default_factory=SimulatedMount)
    start_utc_s: float = 0.0
    sun_irradiance: float = SUN_IRRADIANCE

    def __post_init__(self) -> None:
        super().__post_init__()
        self.bench = replace(self.bench, source_diameter_deg=SUN_DIAMETER_DEG)

    def utc_s(self) -> float:
        """UTC now (Unix seconds)."""
        return self.start_utc_s + self.clock.now()

    def sun_body(self) -> np.ndarray:
        """Unit vector to the Sun's apparent centre in the sensor's body frame."""
        return self.field_mount.to_sensor(self.sky.sun_enu(self.utc_s()))[0]

    def sun_direction_body(self) -> tuple[float, float]:
        """The Sun's (zenith, azimuth) in the body frame [°] (zenith ≥ 90: behind the sensor's face)."""
        x, y, z = self.sun_body()
        return math.degrees(math.acos(max(-1.0, min(1.0, z)))), math.degrees(math.atan2(y, x)) % 360.0

    def clouds(self) -> CloudState:
        return self.sky.cloud_state(self.utc_s())

    def sun_up(self) -> bool:
        return bool(self.sky.sun_enu(self.utc_s())[0, 2] > 0)

    def irradiance(self) -> float:
        """The Sun through the haze (a cloud's edge is in :meth:`occlusion`); 0 at night."""
        return self.sun_irradiance * self.clouds().transmission if self.sun_up() else 0.0

    def occlusion(self) -> tuple[float, float, float] | None:
        state = self.clouds()
        if state.edge_offset_deg >= SUN_DIAMETER_DEG / 2:  # the edge misses the disc
            return None
        offset = max(state.edge_offset_deg, -SUN_DIAMETER_DEG)  # wholly covered: any edge beyond the disc
        return (round(offset, 6), round(state.edge_angle_deg, 3), state.cloud_transmission)


def field_world(sky: SimulatedSky, mount: SimulatedMount, start_utc_s: float, *, base: SimWorld | None = None,
                sun_irradiance: float = SUN_IRRADIANCE, time_scale: float = 0.0) -> FieldWorld:
    """A field world for the sensor of `base` (a bench's world: the same sensor build, seed and temperature), its
    clock at `time_scale` (0: a field day is simulated as fast as it renders; 1: the sky moves in real time, for a
    recorder that sleeps between readings)."""
    from .clock import SimClock

    base = base or SimWorld()
    return FieldWorld(clock=SimClock(time_scale), bench=base.bench, sensor=base.sensor, lamp_spec=base.lamp_spec,
                      seed=base.seed, temperature_c=base.temperature_c, sky=sky, field_mount=mount,
                      start_utc_s=float(start_utc_s), sun_irradiance=sun_irradiance)
