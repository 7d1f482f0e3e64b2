"""The simulated sky of a field run: the real Sun over a site, clouds passing it, and the sensor's mount.

This is the field simulator's own physics, never the comparison's or the locator's model:
- the Sun: its *airless* topocentric position from NREL SPA (pvlib, Reda & Andreas 2004: the ephemeris is the
  truth to ±0.0003°), then bent by the simulated atmosphere's refraction (Sæmundsson's formula, Meeus ch. 16,
  scaled by the site's pressure and temperature), computed here, not by SPA's refraction term. SPA uses the same
  formula, so with the same air the two agree to 1e-12°: the simulated field's errors are the sensor's, the
  mount's and the clouds', and a wrong pressure or temperature given to the comparison shows as its own error;
- the mount: the sensor's frame in the local level frame (east, north, up), by Rodrigues' rotations;
- clouds: a haze that dims the whole disc, and opaque or thin cloud banks whose edges sweep across the Sun, so
  that a partly covered disc has a shape, and a centroid, of its own (seed 003 §5: "clouds spoil it").

Frames: east-north-up (ENU) for the sky, azimuth east of north; the sensor frame has +z out of its face, a
level mount with heading ψ points its +x at azimuth ψ and its +y 90° anticlockwise of it seen from above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

SUN_DIAMETER_DEG = 0.533  # mean apparent diameter of the solar disc [°]


@dataclass(frozen=True)
class CloudState:
    """What stands between the Sun and the sensor at one instant.

    Attributes
    ----------
    transmission : float
        Haze: the fraction of the Sun's light that reaches the sensor through the clear part [0..1].
    edge_offset_deg : float
        Signed angular distance of an opaque cloud's straight edge from the Sun's centre [°]: the cloud covers
        the points of the disc whose offset along `edge_angle_deg` exceeds it (+inf: no edge, a clear disc;
        -inf: the whole disc covered).
    edge_angle_deg : float
        Direction, around the Sun, towards the covered side [°], measured in the sensor frame: 0 along the
        sensor's +x axis projected on the sky at the Sun, 90 along +y (the tangent basis e1 = x̂ − (x̂·s)s
        normalised, e2 = s × e1, with s the Sun's direction).
    cloud_transmission : float
        Fraction of the light that passes through the covered part [0..1] (0: opaque).
    aureole : float
        Light scattered by the cloud into a halo a few degrees wide, as a fraction of the clear disc's flux.
    """

    transmission: float = 1.0
    edge_offset_deg: float = math.inf
    edge_angle_deg: float = 0.0
    cloud_transmission: float = 0.0
    aureole: float = 0.0

    @property
    def clear(self) -> bool:
        """Nothing but (possibly) haze in front of the disc."""
        return self.edge_offset_deg >= SUN_DIAMETER_DEG / 2 and self.aureole == 0.0

    def covered_fraction(self) -> float:
        """Fraction of the disc's area behind the cloud [0..1] (a uniform disc)."""
        r = SUN_DIAMETER_DEG / 2
        d = min(max(self.edge_offset_deg, -r), r) / r
        return float((math.acos(d) - d * math.sqrt(1 - d * d)) / math.pi)


CLEAR = CloudState()


@dataclass(frozen=True)
class CloudBank:
    """One cloud drifting across the Sun: its leading edge reaches the Sun's centre at `start_s`, it covers the
    centre for `duration_s`, and it moves at `speed_deg_s` along `direction_deg` (the direction, around the
    Sun in the sensor's tangent frame, it comes *from*: the covered side while it arrives).

    Times are UTC seconds since the Unix epoch. A bank is wider than the Sun (its edges cross the disc one at a
    time: ``duration_s × speed_deg_s`` at least the disc's diameter)."""

    start_s: float
    duration_s: float
    speed_deg_s: float = 0.002  # a cumulus at 1 km moving at 5 m/s crosses the 0.53° disc in about 4 min
    direction_deg: float = 0.0
    transmission: float = 0.0  # through the cloud
    aureole: float = 0.05  # halo while the cloud is near the Sun

    def __post_init__(self) -> None:
        if not self.speed_deg_s > 0 or self.duration_s * self.speed_deg_s < SUN_DIAMETER_DEG:
            raise ValueError(f"a cloud bank is wider than the Sun's {SUN_DIAMETER_DEG}° disc: duration × speed is "
                             f"{self.duration_s * self.speed_deg_s:.3g}°")

    def state(self, t_s: float) -> CloudState | None:
        """The bank's edge over the disc at `t_s` (None when the bank is far from the Sun)."""
        r = SUN_DIAMETER_DEG / 2
        lead = (t_s - self.start_s) * self.speed_deg_s  # how far the leading edge has passed the centre [°]
        trail = (t_s - self.start_s - self.duration_s) * self.speed_deg_s
        near = 3 * r  # the aureole shows while an edge is within three radii
        if lead < -near or trail > near:
            return None
        if trail < -r and lead > r:  # the disc wholly behind the cloud
            return CloudState(edge_offset_deg=-math.inf, cloud_transmission=self.transmission, aureole=self.aureole)
        if lead <= r:  # the leading edge crosses: the covered side is where the cloud comes from
            return CloudState(edge_offset_deg=-lead, edge_angle_deg=self.direction_deg,
                              cloud_transmission=self.transmission, aureole=self.aureole)
        # the trailing edge crosses: the covered side is the far side
        return CloudState(edge_offset_deg=trail, edge_angle_deg=(self.direction_deg + 180.0) % 360.0,
                          cloud_transmission=self.transmission, aureole=self.aureole)


@dataclass(frozen=True)
class SimulatedSky:
    """The Sun over a site and the clouds of one day (see the module docstring).

    Attributes
    ----------
    latitude_deg, longitude_deg : float
        Site, north and east positive [°].
    altitude_m : float
        Height above sea level [m].
    pressure_hpa, temperature_c : float
        The air the light comes through (refraction).
    delta_t_s : float
        TT − UT [s] used for the ephemeris.
    haze : tuple of (start_s, end_s, transmission)
        Intervals of uniform dimming.
    clouds : tuple of CloudBank
    """

    latitude_deg: float
    longitude_deg: float
    altitude_m: float = 0.0
    pressure_hpa: float = 1013.25
    temperature_c: float = 12.0
    delta_t_s: float = 69.0
    haze: tuple[tuple[float, float, float], ...] = ()
    clouds: tuple[CloudBank, ...] = field(default_factory=tuple)

    def airless_position(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """Topocentric zenith and azimuth (east of north) of the Sun's centre without the atmosphere [°]."""
        from pvlib import spa  # the ephemeris; loaded only for a field simulation

        unix = np.atleast_1d(np.asarray(t_s, dtype=float))
        # pressure 0: SPA's refraction term vanishes, the atmosphere below is this simulator's own
        out = spa.solar_position_numpy(unix, self.latitude_deg, self.longitude_deg, self.altitude_m, 0.0,
                                       self.temperature_c, self.delta_t_s, 0.5667, 1)
        return out[1], out[4]

    def refraction_deg(self, true_elevation_deg) -> np.ndarray:
        """Refraction of a body at `true_elevation_deg` [°] through this air (Sæmundsson 1986, Meeus eq. 16.4,
        scaled by P/1010 hPa and 283 K/T), zero below −1°."""
        h = np.asarray(true_elevation_deg, dtype=float)
        r_arcmin = 1.02 / np.tan(np.radians(h + 10.3 / (h + 5.11)))
        r = r_arcmin / 60.0 * (self.pressure_hpa / 1010.0) * (283.0 / (273.0 + self.temperature_c))
        return np.where(h > -1.0, r, 0.0)

    def apparent_position(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """The Sun's apparent zenith and azimuth (east of north) as the sensor sees it [°]."""
        zenith, azimuth = self.airless_position(t_s)
        return zenith - self.refraction_deg(90.0 - zenith), azimuth

    def sun_enu(self, t_s) -> np.ndarray:
        """Unit vectors (N, 3) to the Sun's apparent centre in east-north-up."""
        zenith, azimuth = (np.radians(a) for a in self.apparent_position(t_s))
        return np.stack([np.sin(zenith) * np.sin(azimuth), np.sin(zenith) * np.cos(azimuth), np.cos(zenith)], -1)

    def cloud_state(self, t_s: float) -> CloudState:
        """Haze and the nearest cloud edge at one instant."""
        transmission = 1.0
        for start, end, tr in self.haze:
            if start <= t_s < end:
                transmission *= tr
        states = [s for s in (bank.state(t_s) for bank in self.clouds) if s is not None]
        if not states:
            return CloudState(transmission=transmission)
        worst = min(states, key=lambda s: s.edge_offset_deg)
        return CloudState(transmission=transmission, edge_offset_deg=worst.edge_offset_deg,
                          edge_angle_deg=worst.edge_angle_deg, cloud_transmission=worst.cloud_transmission,
                          aureole=worst.aureole)


def random_clouds(rng: np.random.Generator, start_s: float, end_s: float, *, banks_per_hour: float = 2.0,
                  mean_duration_s: float = 600.0, transmission_range=(0.0, 0.3)) -> tuple[CloudBank, ...]:
    """Cloud banks at random times over [start_s, end_s) (a Poisson process), random drift directions, speeds
    and durations."""
    end_s = max(end_s, start_s)  # a run may end before the interval
    n = rng.poisson(banks_per_hour * (end_s - start_s) / 3600.0)
    starts = np.sort(rng.uniform(start_s, end_s, n))
    banks = []
    for t in starts:
        speed = float(rng.uniform(0.001, 0.004))
        duration = max(float(rng.exponential(mean_duration_s)), 1.5 * SUN_DIAMETER_DEG / speed)  # wider than the Sun
        banks.append(CloudBank(start_s=float(t), duration_s=duration, speed_deg_s=speed,
                               direction_deg=float(rng.uniform(0, 360)),
                               transmission=float(rng.uniform(*transmission_range)),
                               aureole=float(rng.uniform(0.01, 0.1))))
    return tuple(banks)


def _rodrigues(axis: np.ndarray, angle_deg: float) -> np.ndarray:
    """Rotation matrix by `angle_deg` about the unit `axis` (right-handed)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = math.radians(angle_deg)
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


@dataclass(frozen=True)
class SimulatedMount:
    """The sensor's true attitude on its field mount.

    Attributes
    ----------
    heading_deg : float
        Azimuth (east of north) of the sensor's +x axis when level [°].
    roll_deg, pitch_deg : float
        The mount's tilt: a right-handed turn of the sensor about its own +x axis, then about its own +y axis
        [°] (what a two-axis inclinometer on the sensor reads).
    """

    heading_deg: float = 0.0
    roll_deg: float = 0.0
    pitch_deg: float = 0.0

    def sensor_axes_enu(self) -> np.ndarray:
        """Columns: the sensor's x, y, z axes in east-north-up."""
        psi = math.radians(self.heading_deg)
        level = np.array([[math.sin(psi), -math.cos(psi), 0.0],
                          [math.cos(psi), math.sin(psi), 0.0],
                          [0.0, 0.0, 1.0]])
        x_axis, y_axis = level[:, 0], level[:, 1]
        tilt_x = _rodrigues(x_axis, self.roll_deg)
        y_after = tilt_x @ y_axis
        return _rodrigues(y_after, self.pitch_deg) @ tilt_x @ level

    def to_sensor(self, enu: np.ndarray) -> np.ndarray:
        """Direction vectors (N, 3) from east-north-up into the sensor frame."""
        return np.asarray(enu, dtype=float) @ self.sensor_axes_enu()
