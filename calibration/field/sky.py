"""The Sun's computed position (NREL SPA through pvlib) and the frames between a sensor on a mount and the sky.

Solar position: Reda & Andreas, "Solar position algorithm for solar radiation applications", Solar Energy 76
(2004) 577–589 (NREL/TP-560-34302, rev. 2008), ±0.0003° from −2000 to 6000, as implemented by pvlib
(:func:`pvlib.spa.solar_position_numpy`). Seed 003 §5 compared its field data with it; seed 001 §2.2 B2 used it
forward only. The apparent (refracted) zenith is what a sensor sees; pressure, temperature and ΔT are explicit.

Frames:
- sky: east-north-up (ENU); zenith z from up, azimuth A east of north, d = (sin z sin A, sin z cos A, cos z);
- sensor: +z out of its face (the boresight), the sensor's own zenith θ and azimuth φ from +x towards +y,
  n = (sin θ cos φ, sin θ sin φ, cos θ) (seed 003 eq. 12, :mod:`calibration.geometry`);
- mount: heading ψ is the azimuth of the sensor's +x axis when level; a level sensor's +y points 90°
  anticlockwise of +x seen from above, so φ = ψ − A on a level mount. Roll ρ turns the sensor about its own +x,
  then pitch π about its own +y (right-handed): d_enu = H(ψ) · Rx(ρ) · Ry(π) · n.

Seed 001 (eqs. 8–10) levels a camera's vector with α, β taken from a gravity vector; :func:`mount_from_gravity`
does that for this mount's roll and pitch.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

import numpy as np

from ..errors import FieldDataError
from ..geometry import direction_vector, zenith_azimuth_from_vector

#: SPA's reference case (Reda & Andreas 2004, table A4.1): Golden, Colorado, 2003-10-17 12:30:30 local (UTC−7).
NREL_REFERENCE = {
    "time_utc": "2003-10-17T19:30:30Z", "latitude_deg": 39.742476, "longitude_deg": -105.1786,
    "altitude_m": 1830.14, "pressure_hpa": 820.0, "temperature_c": 11.0, "delta_t_s": 67.0,
    "zenith_deg": 50.11162, "azimuth_deg": 194.34024,  # topocentric zenith (refracted) and azimuth
}


@dataclass(frozen=True)
class Site:
    """Where the sensor stands: latitude and longitude (north and east positive) [°], height above sea [m]."""

    latitude_deg: float
    longitude_deg: float
    altitude_m: float = 0.0

    def __post_init__(self) -> None:
        if not -90.0 <= self.latitude_deg <= 90.0:
            raise FieldDataError(f"latitude must be within ±90°, got {self.latitude_deg}", column="latitude_deg")
        if not -180.0 <= self.longitude_deg <= 360.0:
            raise FieldDataError(f"longitude must be within −180…360°, got {self.longitude_deg}",
                                 column="longitude_deg")
        if not -500.0 <= self.altitude_m <= 9000.0:
            raise FieldDataError(f"altitude must be −500…9000 m, got {self.altitude_m}", column="altitude_m")


@dataclass(frozen=True)
class Atmosphere:
    """The air and the clock behind the apparent position.

    Attributes
    ----------
    pressure_hpa : float
        Station pressure [hPa] (refraction scales with it; 0 gives the airless position).
    temperature_c : float
        Air temperature [°C].
    delta_t_s : float or None
        TT − UT [s]; None takes pvlib's estimate for the date (its polynomial: 71 s for 2019, 75 s for 2026, where
        the measured value is about 69 s; 6 s of ΔT move the Sun by 0.0005° at most).
    refraction_at_horizon_deg : float
        SPA's atmospheric refraction at sunrise and sunset [°].
    """

    pressure_hpa: float = 1013.25
    temperature_c: float = 12.0
    delta_t_s: float | None = None
    refraction_at_horizon_deg: float = 0.5667

    def __post_init__(self) -> None:
        if not 0.0 <= self.pressure_hpa <= 1100.0:
            raise FieldDataError(f"pressure must be 0…1100 hPa, got {self.pressure_hpa}", column="pressure_hpa")
        if not -90.0 <= self.temperature_c <= 60.0:
            raise FieldDataError(f"temperature must be −90…60 °C, got {self.temperature_c}", column="temperature_c")
        if self.delta_t_s is not None and not abs(self.delta_t_s) < 10_000.0:  # NaN fails too
            raise FieldDataError(f"ΔT must be a finite number of seconds under 10 000, got {self.delta_t_s}",
                                 column="delta_t_s")


@dataclass(frozen=True)
class SunPosition:
    """The Sun's centre seen from a site at given times [°] (arrays of one length)."""

    apparent_zenith_deg: np.ndarray
    zenith_deg: np.ndarray  # geometric (no refraction)
    azimuth_deg: np.ndarray  # east of north

    def enu(self) -> np.ndarray:
        """Unit vectors (N, 3) to the apparent Sun in east-north-up."""
        return enu_vector(self.apparent_zenith_deg, self.azimuth_deg)


def utc_seconds(times) -> np.ndarray:
    """Seconds since 1970-01-01 UTC of ISO 8601 strings, datetimes or numpy datetime64 values.

    Strings and datetimes without a zone are taken as UTC (a field file's ``time_utc``); with a zone they are
    converted.

    Raises
    ------
    FieldDataError
        A value that is not a time, naming its position.
    """
    if isinstance(times, np.ndarray) and np.issubdtype(times.dtype, np.datetime64):
        return times.astype("datetime64[ns]").astype(np.int64) / 1e9
    if isinstance(times, str | dt.datetime | np.datetime64):
        times = [times]
    out = np.empty(len(times))
    for i, t in enumerate(times):
        try:
            if isinstance(t, np.datetime64):
                out[i] = t.astype("datetime64[ns]").astype(np.int64) / 1e9
                continue
            stamp = t if isinstance(t, dt.datetime) else dt.datetime.fromisoformat(str(t).strip())
        except ValueError as exc:
            raise FieldDataError(f"time {i}: {t!r} is not an ISO 8601 time ({exc})", row=i,
                                 column="time_utc") from None
        if stamp.tzinfo is None:
            stamp = stamp.replace(tzinfo=dt.UTC)
        out[i] = stamp.timestamp()
    return out


def delta_t_estimate_s(t_s) -> np.ndarray:
    """pvlib's ΔT = TT − UT estimate [s] for the months of the times `t_s` (Unix seconds)."""
    from pvlib import spa

    days = np.asarray(t_s, dtype=float) / 86400.0
    dates = np.datetime64("1970-01-01") + days.astype("timedelta64[D]")
    years = dates.astype("datetime64[Y]").astype(int) + 1970
    months = dates.astype("datetime64[M]").astype(int) % 12 + 1
    return np.asarray(spa.calculate_deltat(years, months), dtype=float)


def sun_position(times, site: Site, atmosphere: Atmosphere = Atmosphere()) -> SunPosition:
    """The Sun's apparent position by NREL SPA (pvlib's numpy implementation).

    Parameters
    ----------
    times : sequence of ISO 8601 strings or datetimes, or an array of Unix seconds (float) or datetime64
        The instants (UTC unless a zone is given).
    site : Site
    atmosphere : Atmosphere

    Returns
    -------
    SunPosition
        Apparent (refracted) and geometric zenith, azimuth east of north [°].

    References
    ----------
    Reda & Andreas (2004), NREL SPA; seed 003 §5 (the field reference), seed 001 §2.2 B2.
    """
    from pvlib import spa  # pandas comes with it; load it only when the Sun is asked for

    t = times_seconds(times)
    delta_t = atmosphere.delta_t_s if atmosphere.delta_t_s is not None else delta_t_estimate_s(t)
    out = spa.solar_position_numpy(t, site.latitude_deg, site.longitude_deg, site.altitude_m,
                                   atmosphere.pressure_hpa, atmosphere.temperature_c, delta_t,
                                   atmosphere.refraction_at_horizon_deg, 1)
    return SunPosition(apparent_zenith_deg=np.asarray(out[0]), zenith_deg=np.asarray(out[1]),
                       azimuth_deg=np.asarray(out[4]))


def times_seconds(times) -> np.ndarray:
    """Unix seconds (1-D) of numbers (taken as Unix seconds already) or of what :func:`utc_seconds` reads."""
    numeric = not isinstance(times, str) and np.asarray(times).dtype.kind in "if"
    return np.atleast_1d(np.asarray(times, dtype=float) if numeric else utc_seconds(times))


def track_arrays(times_s, zenith_deg, azimuth_deg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A track's times [Unix s] and the sensor's θ, φ [°] as 1-D float arrays of one length.

    Raises
    ------
    FieldDataError
        Arrays of different shapes or dimensions.
    """
    t = times_seconds(times_s)
    th = np.atleast_1d(np.asarray(zenith_deg, dtype=float))
    ph = np.atleast_1d(np.asarray(azimuth_deg, dtype=float))
    if not t.shape == th.shape == ph.shape or t.ndim != 1:
        raise FieldDataError(f"times, zenith and azimuth must be 1-D and of one length, got {t.shape}, "
                             f"{th.shape}, {ph.shape}")
    return t, th, ph


def enu_vector(zenith_deg, azimuth_deg) -> np.ndarray:
    """Unit vectors (..., 3) in east-north-up from zenith and azimuth east of north [°]."""
    z = np.radians(np.asarray(zenith_deg, dtype=float))
    a = np.radians(np.asarray(azimuth_deg, dtype=float))
    return np.stack([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)], axis=-1)


def zenith_azimuth_enu(v) -> tuple[np.ndarray, np.ndarray]:
    """Zenith and azimuth east of north [°] (azimuth in [0, 360)) of vectors (..., 3) in east-north-up."""
    v = np.asarray(v, dtype=float)
    norm = np.linalg.norm(v, axis=-1)
    zenith = np.degrees(np.arccos(np.clip(v[..., 2] / norm, -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(v[..., 0], v[..., 1])) % 360.0
    return zenith, azimuth


@dataclass(frozen=True)
class Mount:
    """The sensor's attitude in the sky frame (see the module docstring for the conventions) [°]."""

    heading_deg: float = 0.0
    roll_deg: float = 0.0
    pitch_deg: float = 0.0

    def matrix(self) -> np.ndarray:
        """M with d_enu = M · n_sensor: H(ψ) · Rx(ρ) · Ry(π)."""
        return mount_matrix(self.heading_deg, self.roll_deg, self.pitch_deg)


def mount_matrix(heading_deg: float, roll_deg: float = 0.0, pitch_deg: float = 0.0) -> np.ndarray:
    """Sensor-to-ENU rotation H(ψ) · Rx(ρ) · Ry(π) (columns: the sensor's axes in east-north-up)."""
    psi, rho, pit = (math.radians(a) for a in (heading_deg, roll_deg, pitch_deg))
    heading = np.array([[math.sin(psi), -math.cos(psi), 0.0],
                        [math.cos(psi), math.sin(psi), 0.0],
                        [0.0, 0.0, 1.0]])
    cr, sr, cp, sp = math.cos(rho), math.sin(rho), math.cos(pit), math.sin(pit)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return heading @ rx @ ry


def sky_from_sensor(zenith_deg, azimuth_deg, mount: Mount) -> tuple[np.ndarray, np.ndarray]:
    """The sky's zenith and azimuth (east of north) [°] of directions the sensor reports as (θ, φ) [°]."""
    n = direction_vector(zenith_deg, azimuth_deg)
    return zenith_azimuth_enu(n @ mount.matrix().T)


def sensor_from_sky(zenith_deg, azimuth_deg, mount: Mount) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's own zenith and azimuth (θ, φ) [°] of sky directions (zenith, azimuth east of north) [°]."""
    d = enu_vector(zenith_deg, azimuth_deg)
    return zenith_azimuth_from_vector(d @ mount.matrix())


def mount_from_gravity(up_sensor, heading_deg: float = 0.0) -> Mount:
    """The mount's roll and pitch from the local vertical measured in the sensor frame (an inclinometer's up
    vector: minus the measured gravity) — seed 001 eqs. 8–10's levelling, for this mount's angles.

    With M = H·Rx(ρ)·Ry(π), up in the sensor frame is (−cos ρ sin π, sin ρ, cos ρ cos π).
    """
    u = np.asarray(up_sensor, dtype=float)
    norm = float(np.linalg.norm(u))
    if not norm > 0 or not np.all(np.isfinite(u)):
        raise FieldDataError(f"the up vector must be finite and non-zero, got {u.tolist()}")
    u = u / norm
    roll = math.degrees(math.asin(float(np.clip(u[1], -1.0, 1.0))))
    pitch = math.degrees(math.atan2(-u[0], u[2]))
    return Mount(heading_deg=heading_deg, roll_deg=roll, pitch_deg=pitch)
