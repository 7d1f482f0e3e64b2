"""Orbits' worth of Sun and Earth geometry for a tumbling cube (seed 000's PilsenCUBE), for attitude studies.

A circular orbit of altitude h in the orbit frame (the orbit in its x–y plane, the Sun at the beta angle β out
of it: s = (cos β, 0, sin β)), sampled evenly in argument of latitude u; the satellite at r = (R+h)(cos u, sin u,
0) is in the Earth's cylindrical shadow when r·s < 0 and |r − (r·s)s| < R. The cube tumbles: its attitude at each
sample is an independent uniformly distributed rotation (a slow tumble over many orbits visits every
orientation alike), drawn from `seed`. The Earth is seen at angular radius ρ = asin(R/(R+h)) (65° at 660 km,
seed 000 §2.2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .css_optics import EarthScene

EARTH_RADIUS_KM = 6371.0


@dataclass(frozen=True)
class OrbitSamples:
    """Body-frame geometry of the samples of :func:`orbit_samples`.

    Attributes
    ----------
    sun_body : ndarray (N, 3)
        Unit vector to the Sun in the body frame.
    earth_body : ndarray (N, 3)
        Unit vector to the Earth's centre (nadir) in the body frame.
    sunlit : ndarray of bool (N,)
        The satellite is out of the Earth's shadow.
    earth_radius_deg : float
        The Earth's angular radius ρ [°].
    argument_of_latitude_deg : ndarray (N,)
        Where on the orbit each sample is [°].
    """

    sun_body: np.ndarray
    earth_body: np.ndarray
    sunlit: np.ndarray
    earth_radius_deg: float
    argument_of_latitude_deg: np.ndarray

    def earth(self, i: int, *, albedo: float = 0.3, temperature_k: float = 288.0) -> EarthScene:
        """Sample `i`'s Earth as the head sees it, lit by the Sun where its ground points see the Sun."""
        return EarthScene(tuple(self.earth_body[i]), self.earth_radius_deg, albedo=albedo,
                          temperature_k=temperature_k, sun_direction=tuple(self.sun_body[i]))

    def __len__(self) -> int:
        return len(self.sunlit)


def earth_angular_radius_deg(altitude_km: float) -> float:
    """ρ = asin(R / (R + h)) [°] for a spherical Earth of radius 6371 km."""
    return math.degrees(math.asin(EARTH_RADIUS_KM / (EARTH_RADIUS_KM + altitude_km)))


def orbit_samples(orbits: float = 1.0, samples_per_orbit: int = 360, *, altitude_km: float = 660.0,
                  beta_deg: float = 30.0, seed: int = 0) -> OrbitSamples:
    """Samples along `orbits` circular orbits (module docstring), the cube tumbling."""
    if samples_per_orbit < 1 or orbits <= 0:
        raise ValueError("`orbits` must be positive and `samples_per_orbit` at least 1")
    if altitude_km <= 0:
        raise ValueError(f"`altitude_km` must be positive, got {altitude_km}")
    n = max(1, int(round(orbits * samples_per_orbit)))
    u = np.radians(np.arange(n) * 360.0 / samples_per_orbit)
    b = math.radians(beta_deg)
    sun = np.array([math.cos(b), 0.0, math.sin(b)])
    r_hat = np.stack([np.cos(u), np.sin(u), np.zeros(n)], axis=-1)
    distance = EARTH_RADIUS_KM + altitude_km
    along = distance * (r_hat @ sun)
    off_axis = np.linalg.norm(distance * r_hat - along[:, None] * sun, axis=-1)
    sunlit = ~((along < 0) & (off_axis < EARTH_RADIUS_KM))
    attitude = Rotation.random(n, random_state=np.random.default_rng(seed))  # body → orbit frame
    sun_body = attitude.inv().apply(np.tile(sun, (n, 1)))
    earth_body = attitude.inv().apply(-r_hat)
    return OrbitSamples(sun_body, earth_body, sunlit, earth_angular_radius_deg(altitude_km), np.degrees(u))
