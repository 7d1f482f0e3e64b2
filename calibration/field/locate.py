"""The site (latitude, longitude) and the mount's heading from the Sun's track seen by a sensor (seed 001).

Seed 001 (§2.2 B1–B5) reduced a two-hour track to three fitted points and searched the Earth for the site by a
pattern search on eq. 13, the heading by a recursive sector search on eq. 14 (110 s on 2.8 GHz). Here the
whole track is fitted at once by nonlinear least squares (the digest's §2.3 replacement):

    minimise  Σᵢ |r_i|²,   r_i = ( p_i · e1_i , p_i · e2_i ) · 180/π   [°],
    p_i = M(ψ, ρ, π)ᵀ · s_enu(t_i; φ, λ, h)

where s_enu is the Sun's apparent direction (NREL SPA, :func:`calibration.field.sky.sun_position`) at the
candidate site, M the mount's sensor-to-sky rotation (:class:`calibration.field.sky.Mount`), and (e1_i, e2_i)
an orthonormal basis of the plane perpendicular to the measured unit vector n_i (fixed per sample): the two
small-angle components of the direction error in the sensor frame [°]. The covariance of the estimate is
σ² (JᵀJ)⁻¹, with σ the given direction noise per component or the residuals' own (Σ r² / (2N − p)).

What the Sun's track can tell
-----------------------------
Moving the site by an angle ε on the Earth turns the local vertical by ε; tilting the mount by ε does the same
to the sensor. The Sun's directions in the sensor frame fix only the sensor's attitude relative to the Earth
(three angles): with the level *given* (an inclinometer, ``level="given"``) that attitude yields latitude,
longitude and heading; with the level *fitted* (``level="fit"``) position and tilt trade one for the other
(1° of tilt ≈ 111 km) and only the refraction's dependence on the true elevation (≈ 0.0007° per degree of
zenith at 50°) and the Sun's parallax separate them, so the fit reports a large, honest uncertainty. A constant
tilt error of the given level therefore moves the fix by ≈ 111 km per degree (seed 001 Table 3's 73 km for its
0.6° inclinometer and glue), and a constant zenith bias does about the same, while a constant azimuth bias of
a level sensor is a rotation about the vertical and is absorbed by the heading.

Forward model speed: SPA's site-independent part (ephemeris, nutation, sidereal time, the Sun's geocentric right
ascension and declination) is computed once per time by :class:`SunEphemeris`; each candidate site then costs
only SPA's topocentric steps, through pvlib's own functions in pvlib's order, so the result is *identical* to
:func:`~calibration.field.sky.sun_position` (tests: < 1e-9° at sites 0–100 km and across the globe), not an
approximation.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ..errors import FieldDataError
from ..geometry import direction_vector
from .sky import Atmosphere, Mount, Site, delta_t_estimate_s, mount_matrix, times_seconds, track_arrays

#: WGS84 semi-major axis [km] and first eccentricity squared: local radii of curvature for km offsets.
WGS84_A_KM = 6378.137
WGS84_E2 = 6.69437999014e-3
#: Mean Earth radius [km] (IUGG), for great-circle distances.
EARTH_RADIUS_KM = 6371.0088

LEVEL_MODES = ("given", "fit")


# --------------------------------------------------------------------------------------------------------------
# the forward model


class SunEphemeris:
    """NREL SPA split at the site: the geocentric Sun per time once, the topocentric Sun per candidate site.

    Parameters
    ----------
    times : array of Unix seconds, or ISO 8601 strings / datetimes
        The instants (UTC unless a zone is given).
    atmosphere : Atmosphere
        Pressure and temperature (refraction) and ΔT, as for :func:`~calibration.field.sky.sun_position`.

    Notes
    -----
    pvlib's ``solar_position_numpy(..., sst=True)`` returns the apparent sidereal time ν, the Sun's geocentric
    right ascension α and declination δ; ``esd=True`` the Earth–Sun distance R. Both are independent of the
    site. :meth:`apparent` continues with pvlib's own functions exactly as ``solar_position_numpy`` does (local
    hour angle, parallax, topocentric declination and hour angle, elevation, refraction, azimuth), broadcasting
    over arrays of sites.

    References
    ----------
    Reda & Andreas (2004), NREL SPA §3.8–3.15; seed 001 §2.2 B2.
    """

    def __init__(self, times, atmosphere: Atmosphere = Atmosphere()):
        from pvlib import spa

        t = times_seconds(times)
        if not np.all(np.isfinite(t)):
            raise FieldDataError("times must be finite", column="time_utc")
        delta_t = atmosphere.delta_t_s if atmosphere.delta_t_s is not None else delta_t_estimate_s(t)
        nu, alpha, delta = spa.solar_position_numpy(t, 0.0, 0.0, 0.0, 0.0, 0.0, delta_t, 0.5667, 1, sst=True)
        (radius,) = spa.solar_position_numpy(t, 0.0, 0.0, 0.0, 0.0, 0.0, delta_t, 0.5667, 1, esd=True)
        self.times_s = t
        self.atmosphere = atmosphere
        self._nu, self._alpha, self._delta = np.asarray(nu), np.asarray(alpha), np.asarray(delta)
        self._xi = np.asarray(spa.equatorial_horizontal_parallax(np.asarray(radius)))

    def __len__(self) -> int:
        return self.times_s.size

    def subset(self, index) -> SunEphemeris:
        """The same ephemeris at a subset of its times (an index array or a boolean mask)."""
        out = object.__new__(SunEphemeris)
        out.times_s = self.times_s[index]
        out.atmosphere = self.atmosphere
        out._nu, out._alpha, out._delta = self._nu[index], self._alpha[index], self._delta[index]
        out._xi = self._xi[index]
        return out

    def apparent(self, latitude_deg, longitude_deg, altitude_m=0.0) -> tuple[np.ndarray, np.ndarray]:
        """Apparent (refracted) zenith and azimuth east of north [°] of the Sun from a site.

        `latitude_deg` and `longitude_deg` broadcast against the times: scalars give arrays (N,), columns
        (K, 1) give (K, N) for K sites.
        """
        from pvlib import spa

        lat = np.asarray(latitude_deg, dtype=float)
        lon = np.asarray(longitude_deg, dtype=float)
        elev = np.asarray(altitude_m, dtype=float)
        atm = self.atmosphere
        big_h = spa.local_hour_angle(self._nu, lon, self._alpha)
        u = spa.uterm(lat)
        x = spa.xterm(u, lat, elev)
        y = spa.yterm(u, lat, elev)
        delta_alpha = spa.parallax_sun_right_ascension(x, self._xi, big_h, self._delta)
        delta_prime = spa.topocentric_sun_declination(self._delta, x, y, self._xi, delta_alpha, big_h)
        h_prime = spa.topocentric_local_hour_angle(big_h, delta_alpha)
        e0 = spa.topocentric_elevation_angle_without_atmosphere(lat, delta_prime, h_prime)
        delta_e = spa.atmospheric_refraction_correction(atm.pressure_hpa, atm.temperature_c, e0,
                                                        atm.refraction_at_horizon_deg)
        e = spa.topocentric_elevation_angle(e0, delta_e)
        zenith = spa.topocentric_zenith_angle(e)
        azimuth = spa.topocentric_azimuth_angle(spa.topocentric_astronomers_azimuth(h_prime, delta_prime, lat))
        return np.asarray(zenith), np.asarray(azimuth)

    def enu(self, latitude_deg, longitude_deg, altitude_m=0.0) -> np.ndarray:
        """Unit vectors (..., N, 3) to the apparent Sun in east-north-up from a site (or sites, see
        :meth:`apparent`)."""
        zenith, azimuth = self.apparent(latitude_deg, longitude_deg, altitude_m)
        z, a = np.radians(zenith), np.radians(azimuth)
        return np.stack([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)], axis=-1)


def tangent_basis(n) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) perpendicular to each unit vector n (N, 3) and to each other, e2 = n × e1.

    The helper axis is +z unless n is within ~26° of it (then +x), so the basis is smooth and never singular;
    it is only a frame for the two components of a small direction error.
    """
    n = np.atleast_2d(np.asarray(n, dtype=float))
    helper = np.where((np.abs(n[:, 2]) < 0.9)[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    return e1, e2


# --------------------------------------------------------------------------------------------------------------
# distances and the ellipse


def radii_of_curvature_km(latitude_deg) -> tuple[float, float]:
    """WGS84 meridional (north) and prime-vertical (east) radii of curvature at a latitude [km]."""
    s2 = math.sin(math.radians(float(latitude_deg))) ** 2
    w = math.sqrt(1.0 - WGS84_E2 * s2)
    return WGS84_A_KM * (1.0 - WGS84_E2) / w**3, WGS84_A_KM / w


def offset_km(latitude0_deg, longitude0_deg, latitude_deg, longitude_deg) -> tuple[np.ndarray, np.ndarray]:
    """North and east offsets [km] of points from a reference point, in the local tangent plane (first order,
    metres-accurate for offsets up to ~100 km)."""
    m_km, n_km = radii_of_curvature_km(latitude0_deg)
    dlat = np.radians(np.asarray(latitude_deg, dtype=float) - latitude0_deg)
    dlon = np.radians((np.asarray(longitude_deg, dtype=float) - longitude0_deg + 180.0) % 360.0 - 180.0)
    return m_km * dlat, n_km * math.cos(math.radians(latitude0_deg)) * dlon


def distance_km(latitude_a_deg, longitude_a_deg, latitude_b_deg, longitude_b_deg) -> np.ndarray:
    """Great-circle distance [km] (haversine, mean Earth radius)."""
    pa, pb = np.radians(latitude_a_deg), np.radians(latitude_b_deg)
    dl = np.radians(np.asarray(longitude_b_deg, dtype=float) - np.asarray(longitude_a_deg, dtype=float))
    h = np.sin((pb - pa) / 2) ** 2 + np.cos(pa) * np.cos(pb) * np.sin(dl / 2) ** 2
    return 2.0 * EARTH_RADIUS_KM * np.arcsin(np.sqrt(np.clip(h, 0.0, 1.0)))


@dataclass(frozen=True)
class PositionEllipse:
    """The 1-σ uncertainty ellipse of a fix in the local tangent plane.

    Attributes
    ----------
    semi_major_km, semi_minor_km : float
        1-σ semi-axes [km] (scale by 2.45 for a 95 % region in two dimensions).
    orientation_deg : float
        Azimuth of the major axis, east of north, in [0, 180) [°].
    covariance_km2 : ndarray (2, 2)
        Covariance of the (east, north) offsets [km²].
    center_latitude_deg, center_longitude_deg : float
        The fix.
    """

    semi_major_km: float
    semi_minor_km: float
    orientation_deg: float
    covariance_km2: np.ndarray
    center_latitude_deg: float
    center_longitude_deg: float

    def outline(self, num: int = 73, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Latitude and longitude [°] of `num` points around the ellipse, its semi-axes times `scale` (for a
        map)."""
        t = np.linspace(0.0, 2.0 * np.pi, num)
        az = math.radians(self.orientation_deg)
        major = np.array([math.sin(az), math.cos(az)])  # (east, north)
        minor = np.array([math.cos(az), -math.sin(az)])
        pts = scale * (np.outer(np.cos(t) * self.semi_major_km, major)
                       + np.outer(np.sin(t) * self.semi_minor_km, minor))
        m_km, n_km = radii_of_curvature_km(self.center_latitude_deg)
        lat = self.center_latitude_deg + np.degrees(pts[:, 1] / m_km)
        lon = self.center_longitude_deg + np.degrees(
            pts[:, 0] / (n_km * max(math.cos(math.radians(self.center_latitude_deg)), 1e-9)))
        return lat, lon


def position_ellipse(latitude_deg: float, longitude_deg: float, covariance_deg2) -> PositionEllipse:
    """The 1-σ ellipse [km] of a position whose (latitude, longitude) covariance is `covariance_deg2` [°²]."""
    m_km, n_km = radii_of_curvature_km(latitude_deg)
    k = np.diag([n_km * math.cos(math.radians(latitude_deg)), m_km]) * (math.pi / 180.0)
    c = np.asarray(covariance_deg2, dtype=float)
    c_en = k @ np.array([[c[1, 1], c[0, 1]], [c[0, 1], c[0, 0]]]) @ k  # (east, north)
    values, vectors = np.linalg.eigh(c_en)
    major = vectors[:, 1]
    orientation = math.degrees(math.atan2(major[0], major[1])) % 180.0
    return PositionEllipse(semi_major_km=float(math.sqrt(max(values[1], 0.0))),
                           semi_minor_km=float(math.sqrt(max(values[0], 0.0))), orientation_deg=orientation,
                           covariance_km2=c_en, center_latitude_deg=float(latitude_deg),
                           center_longitude_deg=float(longitude_deg))


# --------------------------------------------------------------------------------------------------------------
# the result


@dataclass(frozen=True)
class SiteFix:
    """A site and heading located from the Sun's track (see the module docstring).

    Attributes
    ----------
    latitude_deg, longitude_deg, altitude_m : float
        The fix (north and east positive, longitude in (−180, 180]); the altitude is the one given.
    heading_deg, roll_deg, pitch_deg : float
        The mount (:class:`~calibration.field.sky.Mount`): heading fitted in [0, 360); roll and pitch fitted
        (``level == "fit"``) or as given.
    parameters : tuple of str
        Names of the fitted parameters, the order of `covariance`.
    sigma_deg : dict
        1-σ of each fitted parameter [°].
    covariance, correlation : ndarray (p, p)
        σ² (JᵀJ)⁻¹ [°²] and its correlation matrix.
    north_sigma_km, east_sigma_km : float
        1-σ of the position along north and east [km].
    ellipse : PositionEllipse
        The 1-σ position ellipse [km].
    residual_rms_deg : float
        RMS of the residual components (each sample has two) [°].
    noise_sigma_deg : float
        The direction noise per component that scales the covariance [°].
    noise_source : str
        ``"given"`` (the caller's σ) or ``"residuals"`` (Σ r² / (2N − p)).
    n_points : int
        Samples used.
    condition_number : float
        Of the Jacobian with its columns scaled to unit length.
    level : str
        ``"given"`` or ``"fit"``.
    warnings : tuple of str
        Identifiability and consistency warnings, in words.
    elapsed_s : float
        Wall time of the solve, the coarse search included [s].
    nfev : int
        Residual evaluations of the final least-squares solve.
    """

    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    heading_deg: float
    roll_deg: float
    pitch_deg: float
    parameters: tuple[str, ...]
    sigma_deg: dict
    covariance: np.ndarray
    correlation: np.ndarray
    north_sigma_km: float
    east_sigma_km: float
    ellipse: PositionEllipse
    residual_rms_deg: float
    noise_sigma_deg: float
    noise_source: str
    n_points: int
    condition_number: float
    level: str
    warnings: tuple[str, ...] = ()
    elapsed_s: float = 0.0
    nfev: int = 0
    residuals_deg: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)

    @property
    def site(self) -> Site:
        return Site(self.latitude_deg, self.longitude_deg, self.altitude_m)

    @property
    def mount(self) -> Mount:
        return Mount(self.heading_deg, self.roll_deg, self.pitch_deg)

    def error_km(self, latitude_deg: float, longitude_deg: float) -> tuple[float, float, float]:
        """North and east offsets of the fix from a true position, and the distance [km]."""
        north, east = offset_km(latitude_deg, longitude_deg, self.latitude_deg, self.longitude_deg)
        return float(north), float(east), float(distance_km(latitude_deg, longitude_deg, self.latitude_deg,
                                                             self.longitude_deg))

    def correlation_of(self, a: str, b: str) -> float:
        """Correlation coefficient of two fitted parameters (by name)."""
        i, j = self.parameters.index(a), self.parameters.index(b)
        return float(self.correlation[i, j])


# --------------------------------------------------------------------------------------------------------------
# the solver


def _fibonacci_sphere(count: int) -> tuple[np.ndarray, np.ndarray]:
    """Latitudes and longitudes [°] of `count` nearly evenly spread points on the sphere."""
    i = np.arange(count) + 0.5
    lat = np.degrees(np.arcsin(1.0 - 2.0 * i / count))
    lon = (np.degrees(np.pi * (1.0 + 5.0**0.5) * i) + 180.0) % 360.0 - 180.0
    return lat, lon


def _closed_form_heading(sun_enu: np.ndarray, level_vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The heading ψ [°] that best turns level-frame vectors w (N, 3) onto Sun vectors d (..., N, 3), and the
    remaining sum of squared chord lengths Σ|H(ψ) w − d|².

    With H(ψ) w = (w_x sin ψ − w_y cos ψ, w_x cos ψ + w_y sin ψ, w_z):  Σ d·Hw = S sin ψ + C cos ψ + Z, with
    S = Σ(d_E w_x + d_N w_y), C = Σ(d_N w_x − d_E w_y), Z = Σ d_U w_U, maximal at ψ = atan2(S, C).
    """
    d, w = sun_enu, level_vectors
    s = np.sum(d[..., 0] * w[:, 0] + d[..., 1] * w[:, 1], axis=-1)
    c = np.sum(d[..., 1] * w[:, 0] - d[..., 0] * w[:, 1], axis=-1)
    z = np.sum(d[..., 2] * w[:, 2], axis=-1)
    heading = np.degrees(np.arctan2(s, c)) % 360.0
    return heading, 2.0 * w.shape[0] - 2.0 * (z + np.hypot(s, c))


def _level_matrix(roll_deg: float, pitch_deg: float) -> np.ndarray:
    """Rx(ρ)·Ry(π): the sensor frame into the level frame whose +x is the heading (H(0) undone)."""
    return mount_matrix(90.0, roll_deg, pitch_deg)  # H(90°) is the identity


def _coarse_search(ephemeris: SunEphemeris, n: np.ndarray, altitude_m: float, roll_deg: float, pitch_deg: float,
                   count: int, keep: int) -> list[tuple[float, float, float]]:
    """The best few (latitude, longitude, heading) of a global grid, each with its closed-form heading."""
    step = max(1, len(ephemeris) // 48)
    idx = np.arange(0, len(ephemeris), step)
    sub = ephemeris.subset(idx)
    w = n[idx] @ _level_matrix(roll_deg, pitch_deg).T
    lat, lon = _fibonacci_sphere(count)
    d = sub.enu(lat[:, None], lon[:, None], altitude_m)
    heading, score = _closed_form_heading(d, w)
    order = np.argsort(score)
    chosen: list[tuple[float, float, float]] = []
    for k in order:
        if all(distance_km(lat[k], lon[k], a, b) > 1500.0 for a, b, _ in chosen):
            chosen.append((float(lat[k]), float(lon[k]), float(heading[k])))
        if len(chosen) == keep:
            break
    return chosen


def _check_inputs(times_s, zenith_deg, azimuth_deg, level: str):
    if level not in LEVEL_MODES:
        raise FieldDataError(f"level must be one of {LEVEL_MODES}, got {level!r}")
    t, th, ph = track_arrays(times_s, zenith_deg, azimuth_deg)
    ok = np.isfinite(t) & np.isfinite(th) & np.isfinite(ph)
    t, th, ph = t[ok], th[ok], ph[ok]
    n_params = 5 if level == "fit" else 3
    min_points = 3 if level == "fit" else 2
    distinct = np.unique(np.round(t, 3)).size
    if distinct < min_points:
        raise FieldDataError(
            f"underdetermined: {distinct} distinct time(s) with a finite direction give {2 * distinct} equations "
            f"for {n_params} unknowns (latitude, longitude, heading" + (", roll, pitch" if level == "fit" else "")
            + f"); need at least {min_points} points with level={level!r}", column="time_utc")
    return t, th, ph


def locate(times_s, zenith_deg, azimuth_deg, *, altitude_m: float = 0.0, atmosphere: Atmosphere = Atmosphere(),
           mount: Mount = Mount(), level: str = "given", sigma_deg: float | None = None,
           initial_site: Site | None = None, initial_heading_deg: float | None = None,
           grid_points: int = 1200, candidates: int = 3, level_sd_deg: float | None = None) -> SiteFix:
    """Latitude, longitude and heading (and the mount's roll and pitch, ``level="fit"``) from the Sun's track.

    Parameters
    ----------
    times_s : array (N,) of Unix seconds (or ISO 8601 strings / datetimes)
        The instants, UTC (:func:`~calibration.field.sky.utc_seconds`).
    zenith_deg, azimuth_deg : array (N,)
        The Sun's direction the sensor measured in its own frame, θ and φ [°] (:mod:`calibration.geometry`).
        Non-finite samples are dropped.
    altitude_m : float
        The site's height above sea level [m], taken as known (its effect is far below any sensor's, seed 001
        §4.2.1 (4)).
    atmosphere : Atmosphere
        Pressure, temperature and ΔT for the Sun's apparent position.
    mount : Mount
        Roll and pitch [°] of the mount when ``level="given"`` (e.g. from an inclinometer,
        :func:`~calibration.field.sky.mount_from_gravity`); the starting point when ``"fit"``. Its heading is
        not used (the heading is always fitted; see `initial_heading_deg`).
    level : {"given", "fit"}
        Whether roll and pitch are known or fitted (see the module docstring: not identifiable from the track
        except through refraction).
    sigma_deg : float or None
        Direction noise per component [°] to scale the covariance; None: estimated from the residuals.
    initial_site : Site or None
        Start the least squares here instead of the global coarse search.
    initial_heading_deg : float or None
        Starting heading [°]; None: the closed-form best heading at the starting site.
    grid_points : int
        Points of the coarse global grid (Fibonacci sphere; 1200 → ~6° spacing).
    candidates : int
        How many of the best, mutually distant (> 1500 km), grid points are refined.
    level_sd_deg : float or None
        1-σ of the given roll and pitch [°] (an inclinometer's accuracy, seed 001's 0.5°; seed 003's precision level
        0.03°): roll and pitch are then fitted with the given values as a Gaussian prior, so the site's
        uncertainty includes the level's — which dominates it (a tilt moves the site by ~111 km per degree).

    Returns
    -------
    SiteFix

    Raises
    ------
    FieldDataError
        Arrays of different lengths, an unknown `level`, or too few points at distinct times (each gives two
        equations: at least 2 for three unknowns, 3 for five with ``level="fit"``).

    References
    ----------
    seed 001 §2.2 B3–B4 (eqs. 13–14, replaced), §2.3 (joint least squares); Reda & Andreas (2004).
    """
    from scipy.optimize import least_squares

    start = _time.perf_counter()
    t, th, ph = _check_inputs(times_s, zenith_deg, azimuth_deg, level)
    n = direction_vector(th, ph)
    e1, e2 = tangent_basis(n)
    ephemeris = SunEphemeris(t, atmosphere)
    if level_sd_deg is not None and not level_sd_deg > 0:
        raise FieldDataError(f"level_sd_deg must be positive, got {level_sd_deg}")
    prior = level_sd_deg is not None  # the level fitted, held to the given one by its stated σ
    fit_level = level == "fit" or prior
    roll0, pitch0 = float(mount.roll_deg), float(mount.pitch_deg)
    prior_weight = 0.0  # (noise / level σ): the prior's rows in the residual's units, set once the noise is known

    def residuals(x: np.ndarray, with_level: bool) -> np.ndarray:
        roll, pitch = (x[3], x[4]) if with_level else (roll0, pitch0)
        s = ephemeris.enu(x[0], x[1], altitude_m)
        p = s @ mount_matrix(x[2], roll, pitch)  # rows: Mᵀ s
        data = np.degrees(np.concatenate([np.sum(p * e1, axis=1), np.sum(p * e2, axis=1)]))
        if with_level and prior:
            return np.concatenate([data, prior_weight * np.array([roll - roll0, pitch - pitch0])])
        return data

    def solve(x0: np.ndarray, with_level: bool):
        lower = np.full(x0.size, -np.inf)
        upper = np.full(x0.size, np.inf)
        lower[0], upper[0] = -90.0, 90.0
        x0 = x0.copy()
        x0[0] = float(np.clip(x0[0], -89.999, 89.999))
        return least_squares(residuals, x0, args=(with_level,), bounds=(lower, upper), method="trf",
                             x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=400)

    if initial_site is not None:
        starts = [(initial_site.latitude_deg, initial_site.longitude_deg)]
        headings = [initial_heading_deg]
    else:
        found = _coarse_search(ephemeris, n, altitude_m, roll0, pitch0, grid_points, candidates)
        starts = [(a, b) for a, b, _ in found]
        headings = [h if initial_heading_deg is None else initial_heading_deg for _, _, h in found]
    best = None
    for (lat0, lon0), psi0 in zip(starts, headings):
        if psi0 is None:
            w = n @ _level_matrix(roll0, pitch0).T
            psi0 = float(_closed_form_heading(ephemeris.enu(lat0, lon0, altitude_m), w)[0])
        sol = solve(np.array([lat0, lon0, psi0]), False)
        if best is None or sol.cost < best.cost:
            best = sol
    def data_noise(rows: np.ndarray, n_free: int) -> float:
        return float(np.sqrt(np.sum(rows**2) / max(rows.size - n_free, 1)))

    if prior:  # the prior's rows weigh noise/σ_level: the noise given, or the residuals' (floored: exact data)
        guess = sigma_deg if sigma_deg is not None else max(data_noise(best.fun, 3), 1e-6)
        prior_weight = float(guess) / float(level_sd_deg)
    if fit_level:
        best = solve(np.concatenate([best.x, [roll0, pitch0]]), True)
        if prior and sigma_deg is None:  # weigh the prior by the noise this fit leaves, once more if it moved
            final = max(data_noise(best.fun[:2 * t.size], 3), 1e-6)
            if abs(final / guess - 1.0) > 0.2:
                prior_weight = final / float(level_sd_deg)
                best = solve(best.x, True)
    x = best.x
    r = best.fun[:2 * t.size]  # the data's rows (without a prior's)
    jac = best.jac[:2 * t.size]
    names = ("latitude", "longitude", "heading") + (("roll", "pitch") if fit_level else ())
    m_eq, p = r.size, x.size - (2 if prior else 0)  # a prior adds two equations for its two unknowns
    rms = float(np.sqrt(np.mean(r**2)))
    if sigma_deg is None:
        dof = max(m_eq - p, 1)
        noise = float(np.sqrt(np.sum(r**2) / dof))
        source = "residuals"
    else:
        noise = float(sigma_deg)
        source = "given"
    # (JᵀJ)⁻¹ of the whitened rows — the data's over the noise, a prior's over the level's σ — through the SVD of
    # the column-scaled Jacobian (stable and honest about near-singular directions)
    whitened = jac / max(noise, 1e-12)
    if prior:
        whitened = np.vstack([whitened, np.eye(5)[3:] / float(level_sd_deg)])
    col = np.linalg.norm(whitened, axis=0)
    col = np.where(col > 0, col, 1.0)
    _, sv, vt = np.linalg.svd(whitened / col, full_matrices=False)
    tiny = np.finfo(float).eps * sv[0] * max(whitened.shape)
    inv_sv2 = 1.0 / np.maximum(sv, tiny) ** 2
    cov = ((vt.T * inv_sv2) @ vt) / np.outer(col, col)
    condition = float(sv[0] / max(sv[-1], tiny))
    sig = np.sqrt(np.diag(cov))
    corr = cov / np.outer(sig, sig)
    lat, lon = float(x[0]), float((x[1] + 180.0) % 360.0 - 180.0)
    if lon == -180.0:
        lon = 180.0
    heading = float(x[2] % 360.0)
    roll, pitch = (float(x[3]), float(x[4])) if fit_level else (roll0, pitch0)
    ellipse = position_ellipse(lat, lon, cov[:2, :2])
    m_km, n_km = radii_of_curvature_km(lat)
    north_sigma = float(m_km * math.radians(sig[0]))
    east_sigma = float(n_km * math.cos(math.radians(lat)) * math.radians(sig[1]))
    warnings = _identifiability_warnings(names, sig, corr, condition, ellipse, t, level == "fit" and not prior, rms,
                                         sigma_deg)
    if best.status <= 0:
        warnings.insert(0, f"the least squares stopped at its limit of {best.nfev} evaluations before converging: "
                           "the fix is not to be trusted (a better starting site, or the level given)")
    if prior:
        warnings.append(f"the level is known to ±{level_sd_deg:g}° (1σ): the position's uncertainty includes it "
                        f"({ellipse.semi_major_km:.3g} km); a tilt moves the site by about 111 km per degree")
    return SiteFix(latitude_deg=lat, longitude_deg=lon, altitude_m=float(altitude_m), heading_deg=heading,
                   roll_deg=roll, pitch_deg=pitch, parameters=names,
                   sigma_deg={k: float(v) for k, v in zip(names, sig)}, covariance=cov, correlation=corr,
                   north_sigma_km=north_sigma, east_sigma_km=east_sigma, ellipse=ellipse, residual_rms_deg=rms,
                   noise_sigma_deg=noise, noise_source=source, n_points=int(t.size), condition_number=condition,
                   level=level, warnings=tuple(warnings), elapsed_s=_time.perf_counter() - start,
                   nfev=int(best.nfev), residuals_deg=r)


def _identifiability_warnings(names, sig, corr, condition, ellipse, t, fit_level, rms, sigma_given) -> list[str]:
    out: list[str] = []
    span_h = float(t.max() - t.min()) / 3600.0
    i_h, i_lon = names.index("heading"), names.index("longitude")
    rho_hl = corr[i_h, i_lon]
    if abs(rho_hl) > 0.9:
        out.append(f"heading and longitude correlate (ρ = {rho_hl:+.3f}) over this {span_h:.2f} h track: a turn "
                   "about the Sun's mean direction mixes them; a longer track separates them")
    big = [(names[i], names[j], corr[i, j]) for i in range(len(names)) for j in range(i + 1, len(names))
           if abs(corr[i, j]) > 0.99 and {names[i], names[j]} != {"heading", "longitude"}]
    for a, b, rho in big:
        out.append(f"{a} and {b} are nearly degenerate (ρ = {rho:+.4f})")
    if fit_level:
        out.append(
            "level fitted: the Sun's track fixes only the sensor's attitude relative to the Earth, so a tilt of the "
            "mount and a shift of the site trade one for the other (1° ≈ 111 km); only refraction and parallax "
            f"separate them here — position 1-σ {ellipse.semi_major_km:.3g} km, roll {sig[3]:.3g}°, "
            f"pitch {sig[4]:.3g}° (not identifiable in practice: give the level from an inclinometer)")
    if condition > 1e8:
        out.append(f"the problem is ill-conditioned (condition number {condition:.2e}): some combination of "
                   "the parameters is not determined by these data")
    if span_h < 0.5 and not fit_level:
        out.append(f"a short track ({span_h * 60:.0f} min): position 1-σ {ellipse.semi_major_km:.3g} km")
    if sigma_given is not None and rms > 3.0 * float(sigma_given):
        out.append(f"the residual RMS {rms:.4f}° is more than 3× the stated noise {float(sigma_given):.4f}°: a "
                   "bias (tilt, zenith error, clock, refraction) or an outlier the noise does not explain")
    return out


def locate_from_points(times_s, zenith_deg, azimuth_deg, **options) -> SiteFix:
    """:func:`locate` for a few points (e.g. seed 001's three fitted points, B1): at least 2 with a given level,
    at least 3 with ``level="fit"``.

    Raises
    ------
    FieldDataError
        Fewer points than that (each point gives two equations; three unknowns, five with the level).
    """
    return locate(times_s, zenith_deg, azimuth_deg, **options)


@dataclass(frozen=True)
class TrackPoints:
    """Seed 001's B1 reduction: fitted points of a track (times in Unix seconds, directions in degrees)."""

    times_s: np.ndarray
    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    max_zenith_residual_deg: float
    max_azimuth_residual_deg: float


def seed001_points(times_s, zenith_deg, azimuth_deg, *, fractions=(0.1, 0.5, 0.9), azimuth_degree: int = 1,
                   zenith_degree: int = 2) -> TrackPoints:
    """Seed 001's curve-fit reduction (B1, eqs. 11–12), for comparison with :func:`locate` on the whole track.

    Azimuth (unwrapped) against time in minutes by a polynomial of `azimuth_degree` (the thesis: 1, a line), zenith
    by one of `zenith_degree` (the thesis: 2); the fitted values at `fractions` of the time span (10/50/90 %).
    The digest (B1) found a line costs 0.3–1.2° over 2 h: raise `azimuth_degree` to 2 or 3 for real use.

    References
    ----------
    seed 001 §2.2 B1, eqs. 11–12.
    """
    t = np.asarray(times_s, dtype=float)
    th = np.asarray(zenith_deg, dtype=float)
    ph = np.degrees(np.unwrap(np.radians(np.asarray(azimuth_deg, dtype=float))))
    if t.size < max(azimuth_degree, zenith_degree) + 1:
        raise FieldDataError(f"{t.size} points cannot carry polynomials of degree {azimuth_degree} and "
                             f"{zenith_degree}")
    minutes = (t - t[0]) / 60.0
    pa = np.polyfit(minutes, ph, azimuth_degree)
    pz = np.polyfit(minutes, th, zenith_degree)
    at = minutes[0] + np.asarray(fractions, dtype=float) * (minutes[-1] - minutes[0])
    return TrackPoints(times_s=t[0] + at * 60.0, zenith_deg=np.polyval(pz, at),
                       azimuth_deg=np.polyval(pa, at) % 360.0,
                       max_zenith_residual_deg=float(np.max(np.abs(np.polyval(pz, minutes) - th))),
                       max_azimuth_residual_deg=float(np.max(np.abs(np.polyval(pa, minutes) - ph))))
