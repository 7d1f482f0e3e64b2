"""Truth data for the field tests, from the field SIMULATOR (drivers.sim.sky): the Sun's apparent position there
is the simulator's own (airless SPA bent by its own refraction), the mount its own Rodrigues rotations.

Noise is added in the sensor frame, independently of the calibration code: each true unit vector is turned by
an angle γ = |g|, g a 2-D Gaussian with σ per component, about a random axis perpendicular to it (so the
zenith and horizontal-arc errors have standard deviation σ each and the vector error RMS σ√2).
"""

import numpy as np

from calibration.field.sky import Atmosphere, Site, utc_seconds
from calibration.geometry import zenith_azimuth_from_vector
from drivers.sim.sky import SimulatedMount, SimulatedSky

#: Seed 001's site (§4.1): Písek, 49.3052028 N, 14.1633511 E, 378 m; a spring morning's air.
PISEK_SKY = SimulatedSky(49.3052028, 14.1633511, 378.0, pressure_hpa=970.0, temperature_c=10.0, delta_t_s=67.0)
PISEK = Site(PISEK_SKY.latitude_deg, PISEK_SKY.longitude_deg, PISEK_SKY.altitude_m)
#: Seed 001's date (18 Apr 2013), a two-hour window 08:00–10:00 UTC (before local noon, ~11:02 UTC).
SPRING_START = float(utc_seconds("2013-04-18T08:00:00")[0])
TRUE_HEADING = 17.3


def atmosphere_of(sky: SimulatedSky) -> Atmosphere:
    """The comparison's Atmosphere for the simulator's air and clock."""
    return Atmosphere(pressure_hpa=sky.pressure_hpa, temperature_c=sky.temperature_c, delta_t_s=sky.delta_t_s)


def site_of(sky: SimulatedSky) -> Site:
    return Site(sky.latitude_deg, sky.longitude_deg, sky.altitude_m)


def track_times(start_s: float = SPRING_START, hours: float = 2.0, step_s: float = 10.0) -> np.ndarray:
    """Sample times [Unix s] from `start_s`, every `step_s`, both ends included."""
    return start_s + np.arange(0.0, hours * 3600.0 + 0.5 * step_s, step_s)


def turn_by_noise(n: np.ndarray, sigma_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Unit vectors (N, 3) turned by a Gaussian angle (σ per component) about random perpendicular axes."""
    n = np.asarray(n, dtype=float)
    if sigma_deg == 0:
        return n.copy()
    r = rng.normal(size=n.shape)
    u = r - np.sum(r * n, axis=1, keepdims=True) * n  # a random direction in the tangent plane (Gram-Schmidt)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    gamma = np.radians(sigma_deg) * np.sqrt(rng.chisquare(2, size=(n.shape[0], 1)))  # |2-D Gaussian|
    return np.cos(gamma) * n + np.sin(gamma) * u


def readings(sky: SimulatedSky, mount: SimulatedMount, times_s, sigma_deg: float = 0.0, rng=None):
    """What a sensor on `mount` reads, θ and φ in its own frame [°], with direction noise σ per component."""
    n = mount.to_sensor(sky.sun_enu(np.asarray(times_s, dtype=float)))
    n = turn_by_noise(n, sigma_deg, rng if rng is not None else np.random.default_rng(0))
    return zenith_azimuth_from_vector(n)
