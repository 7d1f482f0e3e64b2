"""A small truth provider in place of STK: the satellite's state in the thesis' ten windows, the orbit frame, and a
nadir-pointing body with injected roll and pitch (seed 004 §1-3, §3-5, Tables 3-1 and 4-1).

What is assumed (the thesis' STK orbit elements are only in Fig. 6-2, an image absent from the text):

* At each window's start the satellite is **exactly** at Table 4-1's geodetic latitude, longitude and altitude
  (WGS84), so the horizon geometry is the thesis'.
* Its velocity is that of a Kepler orbit of inclination 97.4° and period 94.3 min (Table 3-1) with a zero flight-path
  angle: perpendicular to the geocentric radius, in the plane of that inclination through the position, going north
  or south as the window's argument of latitude says (ascending node just before 07:30, Table 4-1's 0.32°), speed
  from vis-viva. Only its direction matters here: it sets the orbit frame's along-track axis.
* Within a window the satellite moves on the circle of its radius at the speed's angular rate (1 s ≈ 7.6 km). The
  frame is Earth-centred, aligned with ECEF at the window's start; the Earth's rotation during the second is ignored
  (the ellipsoid is symmetric about z, so it changes nothing but longitudes).
* The body is nadir-pointing on the orbit frame (Z_r the geocentric nadir, X_r along track) with the injected roll
  and pitch of :func:`calibration.horizon.scan.body_to_orbit`; the thesis' orbit-frame truth is roll = pitch = 0.
  Yaw is 0. STK's YPR321 in ICRF (Tables 4-4–4-8's "real" columns) cannot be rebuilt without STK's attitude.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import thesis
from .earth import geodetic_to_ecef_km
from .scan import body_to_orbit

#: The Earth's gravitational parameter GM [km³/s²] (WGS84).
MU_KM3_S2 = 398600.4418


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("a zero vector has no direction")
    return v / n


def semi_major_axis_km(period_s, mu_km3_s2=MU_KM3_S2) -> float:
    """a = (μ (T/2π)²)^(1/3) [km] of a Kepler orbit of period T [s] (Table 3-1's 94.3 min → 6861.6 km, seed 004)."""
    if period_s <= 0:
        raise ValueError(f"an orbital period must be positive, got {period_s}")
    return float((mu_km3_s2 * (period_s / (2.0 * np.pi)) ** 2) ** (1.0 / 3.0))


def orbit_frame(position_km, velocity_km_s) -> np.ndarray:
    """The orbit frame (seed 004 §1-3-2: Z_r the geocentric nadir, X_r along track, Y_r = Z_r × X_r) as the rotation
    (…, 3, 3) whose columns are X_r, Y_r, Z_r in the Earth-centred frame (orbit → Earth-centred)."""
    z = -_unit(position_km)
    v = np.asarray(velocity_km_s, float)
    x = _unit(v - np.sum(v * z, axis=-1, keepdims=True) * z)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def body_to_frame(position_km, velocity_km_s, roll_deg=0.0, pitch_deg=0.0) -> np.ndarray:
    """The rotation (…, 3, 3) taking body vectors to the Earth-centred frame for a nadir-pointing body with roll φ
    and pitch θ [°] from the orbit frame: ``orbit_frame · R_y(−θ) R_x(−φ)`` (seed 004 eq. 2.6, orthogonal R_x)."""
    return orbit_frame(position_km, velocity_km_s) @ body_to_orbit(roll_deg, pitch_deg)


def inclined_velocity_direction(position_km, inclination_deg, northbound) -> np.ndarray:
    """The unit direction ⟂ the position, in the orbital plane of inclination i through it, going north
    (`northbound` True) or south: v̂ = ĥ × r̂ with ĥ = (sin i sin Ω, −sin i cos Ω, cos i) and ĥ·r̂ = 0 (seed 004
    Table 3-1's 97.4° orbit). Raises when the position's latitude exceeds what the inclination reaches."""
    r = _unit(position_km)
    inc = np.radians(float(inclination_deg))
    rho = np.hypot(r[0], r[1])
    lon = np.arctan2(r[1], r[0])
    # sin(Ω − λ) = −cot i · z/ρ
    s = -r[2] / (np.tan(inc) * rho) if rho > 0 else np.inf
    if abs(s) > 1.0:
        raise ValueError(f"an orbit of inclination {inclination_deg}° does not reach latitude "
                         f"{np.degrees(np.arcsin(r[2])):.3f}°")
    best = None
    for node in (lon + np.arcsin(s), lon + np.pi - np.arcsin(s)):
        h = np.array([np.sin(inc) * np.sin(node), -np.sin(inc) * np.cos(node), np.cos(inc)])
        v = np.cross(h, r)
        if (v[2] > 0) == bool(northbound) or (v[2] == 0 and best is None):
            best = v
    return _unit(best)


@dataclass(frozen=True)
class SatelliteState:
    """The satellite at one instant: Earth-centred position [km] and inertial velocity [km/s] (seed 004 §3-5)."""

    time_s: float
    position_km: np.ndarray
    velocity_km_s: np.ndarray

    def orbit_frame(self) -> np.ndarray:
        """The orbit frame's axes as columns (orbit → Earth-centred), seed 004 §1-3-2."""
        return orbit_frame(self.position_km, self.velocity_km_s)

    def body_to_frame(self, roll_deg=0.0, pitch_deg=0.0) -> np.ndarray:
        """Body → Earth-centred for a nadir-pointing body at roll, pitch [°] (seed 004 eq. 2.6)."""
        return body_to_frame(self.position_km, self.velocity_km_s, roll_deg, pitch_deg)


def propagate_circular(state: SatelliteState, dt_s) -> SatelliteState:
    """The state `dt_s` [s] later on the circle of the state's radius, at angular rate |v|/|r| about the orbit normal
    r × v (seed 004 §3-5: 1-s windows; eccentricity changes the radius by ~20 m in a second, ignored)."""
    r, v = np.asarray(state.position_km, float), np.asarray(state.velocity_km_s, float)
    normal = _unit(np.cross(r, v))
    angle = np.linalg.norm(v) / np.linalg.norm(r) * float(dt_s)
    c, s = np.cos(angle), np.sin(angle)

    def turn(x):  # Rodrigues about the orbit normal
        return x * c + np.cross(normal, x) * s + normal * np.dot(normal, x) * (1.0 - c)

    return SatelliteState(state.time_s + float(dt_s), turn(r), turn(v))


def window_argument_of_latitude_deg(window) -> float:
    """The argument of latitude [°] at a thesis window's start: Table 4-1's 0.32° at 07:30 (just after the ascending
    node) advanced at 360° per 94.3 min (seed 004 Tables 3-1, 4-1)."""
    i = thesis.window_index(window)
    h, m, s = (int(x) for x in thesis.WINDOWS[i].split(":"))
    minutes = (h - 7) * 60 + (m - 30) + s / 60.0
    inc = np.radians(thesis.MICROMAS_INCLINATION_DEG)
    u0 = np.degrees(np.arcsin(np.sin(np.radians(thesis.TABLE_4_1_LATITUDE_DEG[0])) / np.sin(inc)))
    return float((u0 + 360.0 * minutes / thesis.MICROMAS_PERIOD_MIN) % 360.0)


def thesis_window_state(window, t_s=0.0) -> SatelliteState:
    """The satellite `t_s` [s] after the start of a thesis window (index 0–9 or "HH:MM"): at Table 4-1's geodetic
    latitude, longitude and altitude at the start, with the assumptions of this module (seed 004 Tables 3-1, 4-1)."""
    i = thesis.window_index(window)
    position = geodetic_to_ecef_km(thesis.TABLE_4_1_LATITUDE_DEG[i], thesis.TABLE_4_1_LONGITUDE_DEG[i],
                                   thesis.TABLE_4_1_ALTITUDE_KM[i])
    northbound = np.cos(np.radians(window_argument_of_latitude_deg(i))) > 0
    direction = inclined_velocity_direction(position, thesis.MICROMAS_INCLINATION_DEG, northbound)
    a = semi_major_axis_km(thesis.MICROMAS_PERIOD_MIN * 60.0)
    speed = np.sqrt(MU_KM3_S2 * (2.0 / np.linalg.norm(position) - 1.0 / a))
    start = SatelliteState(0.0, position, speed * direction)
    return propagate_circular(start, t_s) if t_s else start
