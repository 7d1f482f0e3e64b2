"""Corrections that take the field of view's and the atmosphere's roll and pitch errors away (issue 15; seed 004
§4-4, §4-5, Table 5-1 and its future-work item 3, "improve the locator to cut the atmosphere-induced error").

The idea is one quantity, the **effective horizon height** h*: the signed tangent height [km] at which the
boresight sits when the locator fires. It is what a solver must use as the horizon (seed 004 eq. 2.3's H_eq, or the
height of a grown WGS84 ellipsoid), instead of the surface:

* **IFOV with the 50 % locator**: on a sphere the locator fires at the separation
  :func:`calibration.horizon.ifov.level_separation_deg` (the limb is curved), i.e. at h* ≈ −0.2 km for the thesis'
  sensor (:func:`ifov_horizon_height_km`).
* **Atmosphere with a normalised threshold locator**: the pulse is the IFOV's mean of the limb radiance; the
  locator fires where it equals C1 × its maximum. On a sphere with a horizontally uniform atmosphere that is a 1-D
  problem in the boresight's separation from nadir (:func:`effective_horizon_height_km`). Through the thesis' 2°
  IFOV h* ≈ 17 km for the US 1976 profile and 11–26 km across the climatologies (the IFOV averages in the bright
  disc; a point boresight would fire at 36–42 km, the classical CO2 horizon) — a latitude- and season-dependent
  horizon, which on a north–south orbit puts the forward and backward crossings at different heights (pitch).
* **Per crossing**: each crossing's h* from the profile at its tangent point's latitude and the day of year
  (:func:`calibration.horizon.atmosphere.seasonal_profile`), the tangent points found from a first solution
  (:func:`corrected_roll_pitch`).

* **Any locator, honestly**: :class:`ClimatologyPulseModel` is all a correction may know of the atmosphere
  (latitude + day of year, one band model); :func:`locator_corrected_roll_pitch` predicts each edge's pulse from it at
  the current estimate, runs the same edge locator (:func:`calibration.horizon.locator.locate_edge`) on the
  prediction and solves with the boresight's tangent heights there. Against a truth with weather, another band
  model and a polar cold pool (tests/calibration/horizon/test_atmosphere_robustness.py) the best locator leaves
  ~0.024° / 0.008° mean roll / pitch, max 0.08° / 0.02°: the day's weather moves each horizon by ~1 km (0.022°).

The solvers here: :func:`fit_roll_pitch_sphere` (least squares on scan.py's closed form, seed 004 eq. 2.7 corrected,
with a ρ per crossing) and :func:`fit_roll_pitch_wgs84`, which needs the satellite's position (as the thesis' oblate
solution does, eqs. 2.23–2.26) and asks each measured crossing direction to be a ray whose tangent height over WGS84
is that crossing's h*; its residuals are in km of tangent height, which is ρ's natural unit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, least_squares

from .atmosphere import CO2_BAND, BandModel, RadianceTable, radiance_table, seasonal_profile, tangent_height_of_angle_km
from .ifov import level_separation_deg, ring_mean_sphere
from .locator import locate_edge
from .oblate import crossing_phases_oblate
from .pulse import tangent_height_scaled_km, wgs84_pulse
from .scan import (
    EQUATORIAL_RADIUS_KM,
    THESIS_GAMMA_DEG,
    THESIS_IFOV_HALF_ANGLE_DEG,
    body_to_orbit,
    crossing_phases,
    earth_angular_radius_deg,
    scan_vector,
)


def ifov_horizon_height_km(altitude_km, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, level=0.5,
                           radius_km=EQUATORIAL_RADIUS_KM) -> np.ndarray:
    """The effective horizon height [km] of the obscuration locator (seed 004 eq. 2.1, C1 = `level`, §4-4) over a
    sphere seen from `altitude_km`: (R + h) sin d_level − R with d_level from
    :func:`calibration.horizon.ifov.level_separation_deg`. −0.21 km for the thesis' sensor at 505 km (negative: the
    50 % point lies inside the disc because the limb is curved)."""
    rho = earth_angular_radius_deg(altitude_km, radius_km)
    return tangent_height_of_angle_km(level_separation_deg(rho, half_angle_deg, level), altitude_km, radius_km)


def pulse_of_separation(radiance: Callable[[np.ndarray], np.ndarray], separation_deg, altitude_km,
                        half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, radius_km=EQUATORIAL_RADIUS_KM,
                        n_rings: int = 800) -> np.ndarray:
    """A top-hat IFOV's mean radiance against the boresight's separation from nadir [°] over a sphere with a
    horizontally uniform atmosphere (seed 004 §2-4-3): the exact ring sum with breaks at ρ and at the 100 km cut."""
    rho = float(earth_angular_radius_deg(altitude_km, radius_km))
    top = float(np.degrees(np.arcsin(min((radius_km + 100.0) / (radius_km + altitude_km), 1.0))))

    def field(eta_deg):
        return radiance(tangent_height_of_angle_km(eta_deg, altitude_km, radius_km))

    return ring_mean_sphere(separation_deg, field, half_angle_deg, (rho, top), n_rings)


def effective_horizon_height_km(radiance: Callable[[np.ndarray], np.ndarray], altitude_km: float,
                                nearest_separation_deg: float = 20.0, level: float = 0.5,
                                half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG,
                                radius_km=EQUATORIAL_RADIUS_KM) -> float:
    """The signed tangent height h* [km] at which a normalised constant locator (seed 004 eq. 2.1, C1 = `level`)
    fires on the pulse of a top-hat IFOV over a spherical Earth with the limb radiance `radiance` (a function of
    signed tangent height), seen from `altitude_km`.

    The pulse's maximum is taken over separations from `nearest_separation_deg` (the scan's closest approach to
    nadir: 90° − γ = 20° for the thesis' sensor at zero attitude) out to the horizon; the crossing is the outermost
    separation where the pulse equals C1 × that maximum, found on a grid (0.5° over the disc, 0.05° across the limb)
    and refined by Brent's method.
    """
    if not 0 < level < 1:
        raise ValueError(f"the locator's level must lie strictly between 0 and 1, got {level!r}")
    rho = float(earth_angular_radius_deg(altitude_km, radius_km))
    limb = rho - half_angle_deg - 0.5
    grid = np.concatenate([np.arange(nearest_separation_deg, limb, 0.5), np.arange(limb, rho + half_angle_deg + 3.0,
                                                                                   0.05)])
    values = pulse_of_separation(radiance, grid, altitude_km, half_angle_deg, radius_km, n_rings=200)  # to bracket
    threshold = level * float(pulse_of_separation(radiance, grid[int(np.argmax(values))], altitude_km,
                                                  half_angle_deg, radius_km))
    above = np.nonzero(values >= threshold)[0]
    if above.size == 0 or above[-1] + 1 >= grid.size:
        raise ValueError("the pulse does not fall through the locator's level beyond the horizon")
    crossing = brentq(lambda d: float(pulse_of_separation(radiance, d, altitude_km, half_angle_deg, radius_km))
                      - threshold, grid[max(above[-1] - 1, 0)], grid[min(above[-1] + 2, grid.size - 1)],
                      xtol=1e-10)  # one step of slack each side: the coarse grid only brackets
    return float(tangent_height_of_angle_km(crossing, altitude_km, radius_km))


def fit_roll_pitch_sphere(phases_deg: Sequence[float], cones: Sequence[int], edges: Sequence[str], rho_deg,
                          gamma_deg=THESIS_GAMMA_DEG, initial=(0.0, 0.0)) -> tuple[float, float]:
    """Roll and pitch [°] from crossing phases on a spherical horizon (seed 004 eq. 2.7 corrected, 2–4 crossings),
    least squares on :func:`calibration.horizon.scan.crossing_phases` with a disc radius ρ per crossing (`rho_deg`:
    one value or one per crossing — the thesis-like solution uses eq. 2.3's ρ for all). `edges` are ``"out"`` or
    ``"in"`` per crossing, `cones` 1 or 2."""
    phases = np.asarray(phases_deg, float)
    rho = np.broadcast_to(np.asarray(rho_deg, float), phases.shape)
    if len(cones) != phases.size or len(edges) != phases.size or phases.size < 2:
        raise ValueError("give at least two crossings, each with its cone and edge")
    if any(e not in ("out", "in") for e in edges):
        raise ValueError("each edge is 'out' or 'in'")
    pick = np.array([0 if e == "out" else 1 for e in edges])
    cone_arr = np.asarray(cones)

    def residual(x):
        out = []
        for k in range(phases.size):
            pair = crossing_phases(x[0], x[1], rho[k], gamma_deg, cone_arr[k])
            out.append((pair[pick[k]] - phases[k] + 180.0) % 360.0 - 180.0)
        r = np.asarray(out, float)
        return np.where(np.isfinite(r), r, 90.0)

    sol = least_squares(residual, np.asarray(initial, float), xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return float(sol.x[0]), float(sol.x[1])


def crossing_directions(phases_deg, cones, roll_deg, pitch_deg, orbit_to_frame,
                        gamma_deg=THESIS_GAMMA_DEG) -> np.ndarray:
    """The boresight directions (n, 3) in the Earth-centred frame at the crossing phases for an attitude: orbit →
    frame · R_y(−θ) R_x(−φ) · S_k(δ) (seed 004 eqs. 2.5–2.6)."""
    s = scan_vector(np.atleast_1d(np.asarray(phases_deg, float)), gamma_deg, np.atleast_1d(np.asarray(cones)))
    return s @ (np.asarray(orbit_to_frame, float) @ body_to_orbit(roll_deg, pitch_deg)).T


def fit_roll_pitch_wgs84(phases_deg, cones, position_km, orbit_to_frame, horizon_heights_km=0.0,
                         gamma_deg=THESIS_GAMMA_DEG, initial=(0.0, 0.0)) -> tuple[float, float]:
    """Roll and pitch [°] from crossing phases over WGS84 with the satellite's position known (seed 004 §2-4-1,
    eqs. 2.9–2.22 in effect): each crossing's boresight, rotated by the attitude, must be a ray whose geodetic tangent
    height is that crossing's effective horizon height h*_k (`horizon_heights_km`: one or one per crossing).

    Residuals are tangent heights [km] (:func:`calibration.horizon.pulse.tangent_height_scaled_km`, ~1 m), solved by
    least squares (2–4 crossings). `orbit_to_frame` (3, 3) has the orbit frame's X_r, Y_r, Z_r as columns.
    """
    phases = np.atleast_1d(np.asarray(phases_deg, float))
    heights = np.broadcast_to(np.asarray(horizon_heights_km, float), phases.shape)
    if phases.size < 2 or len(np.atleast_1d(cones)) != phases.size:
        raise ValueError("give at least two crossings, each with its cone")
    p = np.asarray(position_km, float)
    body = scan_vector(phases, gamma_deg, np.atleast_1d(np.asarray(cones)))  # fixed: only the attitude moves
    frame = np.asarray(orbit_to_frame, float)

    def residual(x):
        return tangent_height_scaled_km(p, body @ (frame @ body_to_orbit(x[0], x[1])).T) - heights

    sol = least_squares(residual, np.asarray(initial, float), method="lm", x_scale=0.01, xtol=1e-13, ftol=1e-13,
                        gtol=1e-13)
    return float(sol.x[0]), float(sol.x[1])


def tangent_latitudes_deg(phases_deg, cones, roll_deg, pitch_deg, position_km, orbit_to_frame,
                          gamma_deg=THESIS_GAMMA_DEG) -> np.ndarray:
    """Geocentric latitudes [°] of the crossings' tangent points (the closest approach of each crossing ray to the
    Earth's centre, near enough to pick a climatological profile), for an attitude estimate (seed 004 eqs. 2.5–2.6,
    §2-4-4's latitude dependence)."""
    dirs = crossing_directions(phases_deg, cones, roll_deg, pitch_deg, orbit_to_frame, gamma_deg)
    p = np.asarray(position_km, float)
    s = -dirs @ p
    point = p + s[:, None] * dirs
    return np.degrees(np.arcsin(point[:, 2] / np.linalg.norm(point, axis=-1)))


@dataclass
class HorizonHeightModel:
    """Effective horizon heights h* per crossing from latitude and season (seed 004 §2-4-3, §2-4-4): the profile
    of :func:`calibration.horizon.atmosphere.seasonal_profile` at the tangent point, its radiance table, and
    :func:`effective_horizon_height_km` for the sensor's IFOV and locator level. Heights are cached per whole
    degree of latitude. `profile_name` fixes one profile for every latitude instead (a model without climatology)."""

    altitude_km: float
    day_of_year: float = 103.0
    level: float = 0.5
    half_angle_deg: float = THESIS_IFOV_HALF_ANGLE_DEG
    nearest_separation_deg: float = 90.0 - THESIS_GAMMA_DEG
    profile_name: str | None = None

    def __post_init__(self):
        self._cache: dict[int, float] = {}

    def table(self, latitude_deg: float) -> RadianceTable:
        """The radiance table for a latitude (or the fixed profile)."""
        if self.profile_name is not None:
            return radiance_table(self.profile_name, step_km=0.25)
        return radiance_table(seasonal_profile(float(np.round(latitude_deg)), self.day_of_year), step_km=0.25)

    def __call__(self, latitudes_deg) -> np.ndarray:
        out = []
        for lat in np.atleast_1d(latitudes_deg):
            key = 0 if self.profile_name is not None else int(np.round(lat))
            if key not in self._cache:
                self._cache[key] = effective_horizon_height_km(self.table(lat), self.altitude_km,
                                                               self.nearest_separation_deg, self.level,
                                                               self.half_angle_deg)
            out.append(self._cache[key])
        return np.asarray(out)


def corrected_roll_pitch(phases_deg, cones, position_km, orbit_to_frame, heights: HorizonHeightModel | None = None,
                         gamma_deg=THESIS_GAMMA_DEG, iterations: int = 2) -> tuple[float, float]:
    """Roll and pitch [°] with the corrections of seed 004's IFOV and atmosphere cases (§4-4, §4-5):
    :func:`fit_roll_pitch_wgs84` with each crossing's effective horizon
    height from `heights` (the atmosphere's h* at the crossing's tangent latitude), iterated (`iterations` times) as
    the tangent points move with the attitude; without `heights`, the IFOV's 50 % height
    (:func:`ifov_horizon_height_km` at the satellite's altitude over a sphere of radius a)."""
    p = np.asarray(position_km, float)
    if heights is None:
        altitude = float(np.linalg.norm(p) - EQUATORIAL_RADIUS_KM)
        return fit_roll_pitch_wgs84(phases_deg, cones, p, orbit_to_frame, float(ifov_horizon_height_km(altitude)),
                                    gamma_deg)
    roll, pitch = 0.0, 0.0
    h = heights(tangent_latitudes_deg(phases_deg, cones, roll, pitch, p, orbit_to_frame, gamma_deg))
    for _ in range(iterations):
        roll, pitch = fit_roll_pitch_wgs84(phases_deg, cones, p, orbit_to_frame, h, gamma_deg, (roll, pitch))
        h = heights(tangent_latitudes_deg(phases_deg, cones, roll, pitch, p, orbit_to_frame, gamma_deg))
    return fit_roll_pitch_wgs84(phases_deg, cones, p, orbit_to_frame, h, gamma_deg, (roll, pitch))


# --- A correction for any locator, honest about what it knows (issue 15; seed 004 §4-5, future-work item 3).
# The correction knows the geometry, the sensor (IFOV, sample clock, locator) and a climatology (latitude and day of
# year); it does not know the day's weather. It predicts each edge's pulse from the climatology at the current
# attitude estimate, runs the locator on the prediction, and takes the boresight's tangent height there as that
# crossing's h* — whatever the locator.

#: The crossing order of the solvers here: cone 1 out, cone 1 in, cone 2 out, cone 2 in.
CROSSINGS = ((1, "out"), (1, "in"), (2, "out"), (2, "in"))
#: The thesis' atmosphere-case sample step, 10⁻³ s at 1 rev/s, in degrees of phase (seed 004 §3-5).
THESIS_ATMOSPHERE_STEP_DEG = 0.36
#: Signed tangent height [km] of the horizon the edge windows are centred on: the middle of the 14–16 µm limb.
WINDOW_CENTRE_HEIGHT_KM = 20.0


@dataclass(frozen=True)
class EdgeWindow:
    """One edge of one cone's pulse, sampled on the sensor's clock: phases [°] (ascending), the pulse, and the
    crossing it holds (seed 004 §2-2)."""

    cone: int
    edge: str
    phase_deg: np.ndarray
    pulse: np.ndarray


def window_phases_deg(centre_deg: float, half_width_deg: float = 8.0,
                      step_deg: float = THESIS_ATMOSPHERE_STEP_DEG) -> np.ndarray:
    """The sample phases [°] within `centre_deg` ± `half_width_deg`: whole multiples of `step_deg` from the scan's
    reference, as a sensor sampling every T·step/360° from its index mark takes them (seed 004 §3-5)."""
    if not step_deg > 0 or not half_width_deg > step_deg:
        raise ValueError("the step must be positive and the window's half-width larger than a step")
    first = np.ceil((centre_deg - half_width_deg) / step_deg)
    last = np.floor((centre_deg + half_width_deg) / step_deg)
    return step_deg * np.arange(first, last + 1.0)


def sub_satellite_latitude_deg(position_km) -> float:
    """The geocentric latitude [°] of the satellite's position (where the pulse's brightest disc lies)."""
    p = np.asarray(position_km, float)
    return float(np.degrees(np.arcsin(p[2] / np.linalg.norm(p))))


def crossing_tangent_latitudes_deg(position_km, body_to_frame, gamma_deg=THESIS_GAMMA_DEG,
                                   height_km: float = WINDOW_CENTRE_HEIGHT_KM) -> tuple[np.ndarray, np.ndarray]:
    """The four crossings' phases [°] on the WGS84 ellipsoid grown by `height_km` and their tangent points'
    geocentric latitudes [°], in :data:`CROSSINGS` order (seed 004 eqs. 2.10–2.23 via
    :func:`calibration.horizon.oblate.crossing_phases_oblate`)."""
    p = np.asarray(position_km, float)
    rot = np.asarray(body_to_frame, float)
    phases = []
    for cone, edge in CROSSINGS:
        out, inn = crossing_phases_oblate(p, rot, gamma_deg, cone, emitting_height_km=height_km)
        phases.append(float(out if edge == "out" else inn))
    dirs = np.stack([scan_vector(ph, gamma_deg, c) for ph, (c, _) in zip(phases, CROSSINGS)]) @ rot.T
    point = p + (-(dirs @ p))[:, None] * dirs
    return np.asarray(phases), np.degrees(np.arcsin(point[:, 2] / np.linalg.norm(point, axis=-1)))


def simulate_edge_windows(position_km, body_to_frame, crossing_radiance: Sequence[Callable], disc_radiance: Callable,
                          gamma_deg=THESIS_GAMMA_DEG, half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG,
                          step_deg: float = THESIS_ATMOSPHERE_STEP_DEG, half_width_deg: float = 8.0):
    """The four edge windows of a top-hat IFOV's pulse over WGS84 and each cone's peak (seed 004 §2-4-3):
    ``(windows, peaks)``, windows in :data:`CROSSINGS` order, peaks ``{cone: α_max}``.

    Each window (±`half_width_deg` about the crossing of the ellipsoid grown by :data:`WINDOW_CENTRE_HEIGHT_KM`)
    sees a horizontally uniform atmosphere, its entry of `crossing_radiance` (4 functions of signed tangent height,
    :data:`CROSSINGS` order); the disc away from the edges sees `disc_radiance`, the atmosphere below the satellite,
    sampled at the scan's closest approach to nadir and ±15° of phase. A cone's peak is the largest sample of its
    windows and of its disc samples — the α_max of seed 004 eq. 2.1.
    """
    if len(crossing_radiance) != len(CROSSINGS):
        raise ValueError(f"give one radiance per crossing ({len(CROSSINGS)}), got {len(crossing_radiance)}")
    p = np.asarray(position_km, float)
    rot = np.asarray(body_to_frame, float)
    centres, _ = crossing_tangent_latitudes_deg(p, rot, gamma_deg)
    windows = []
    for (cone, edge), centre, radiance in zip(CROSSINGS, centres, crossing_radiance):
        phase = window_phases_deg(centre, half_width_deg, step_deg)
        values = wgs84_pulse(phase, p, rot, radiance, half_angle_deg, gamma_deg=gamma_deg, cone=cone)
        windows.append(EdgeWindow(cone, edge, phase, values))
    nadir_body = rot.T @ (-p / np.linalg.norm(p))
    closest = float(np.degrees(np.arctan2(nadir_body[0], nadir_body[2])))
    peaks = {}
    for cone in (1, 2):
        disc = wgs84_pulse(closest + np.array([-15.0, 0.0, 15.0]), p, rot, disc_radiance, half_angle_deg,
                           gamma_deg=gamma_deg, cone=cone)
        peaks[cone] = float(max(disc.max(), *(w.pulse.max() for w in windows if w.cone == cone)))
    return windows, peaks


def locate_windows(method: str, windows: Sequence[EdgeWindow], peaks: dict, **options) -> np.ndarray:
    """Each window's crossing phase [°] by the edge locator `method`
    (:func:`calibration.horizon.locator.locate_edge`; seed 004 eqs. 2.1–2.2 and the derivative locators)."""
    return np.array([locate_edge(method, w.phase_deg, w.pulse, w.edge, peaks[w.cone], **options) for w in windows])


@dataclass
class ClimatologyPulseModel:
    """What a correction may know of the atmosphere: the climatology at a latitude and day of year
    (:func:`calibration.horizon.atmosphere.seasonal_profile`, or one fixed profile `profile_name`) and a band model
    (seed 004 §2-4-3, §2-4-4). Radiance tables are cached per whole degree of latitude."""

    day_of_year: float = 103.0
    band: BandModel = CO2_BAND
    profile_name: str | None = None
    step_km: float = 0.5

    def __post_init__(self):
        self._tables: dict[int, RadianceTable] = {}

    def radiance(self, latitude_deg: float) -> RadianceTable:
        """The climatological limb radiance at a latitude [°] (a function of signed tangent height)."""
        key = 0 if self.profile_name is not None else int(np.round(latitude_deg))
        if key not in self._tables:
            prof = self.profile_name if self.profile_name is not None else seasonal_profile(key, self.day_of_year)
            self._tables[key] = radiance_table(prof, self.band, step_km=self.step_km)
        return self._tables[key]

    def edge_windows(self, position_km, body_to_frame, gamma_deg=THESIS_GAMMA_DEG,
                     half_angle_deg=THESIS_IFOV_HALF_ANGLE_DEG, step_deg: float = THESIS_ATMOSPHERE_STEP_DEG,
                     half_width_deg: float = 8.0):
        """:func:`simulate_edge_windows` with the climatology at each crossing's tangent latitude and below the
        satellite."""
        _, latitudes = crossing_tangent_latitudes_deg(position_km, body_to_frame, gamma_deg)
        return simulate_edge_windows(position_km, body_to_frame, [self.radiance(lat) for lat in latitudes],
                                     self.radiance(sub_satellite_latitude_deg(position_km)), gamma_deg,
                                     half_angle_deg, step_deg, half_width_deg)


def locator_horizon_heights_km(method: str, windows: Sequence[EdgeWindow], peaks: dict, position_km,
                               body_to_frame, gamma_deg=THESIS_GAMMA_DEG, **options) -> np.ndarray:
    """Each predicted window's h* [km]: the boresight's signed tangent height over WGS84 at the phase where the
    locator fires on it (:func:`calibration.horizon.pulse.tangent_height_scaled_km`; seed 004 eq. 2.3's H_eq per
    crossing)."""
    phases = locate_windows(method, windows, peaks, **options)
    dirs = np.stack([scan_vector(ph, gamma_deg, w.cone) for ph, w in zip(phases, windows)])
    return tangent_height_scaled_km(np.asarray(position_km, float), dirs @ np.asarray(body_to_frame, float).T)


def locator_corrected_roll_pitch(phases_deg, position_km, orbit_to_frame, method: str,
                                 model: ClimatologyPulseModel | None, gamma_deg=THESIS_GAMMA_DEG,
                                 iterations: int = 1, initial=None, **options) -> tuple[float, float]:
    """Roll and pitch [°] from four measured crossing phases (:data:`CROSSINGS` order) with the atmosphere's
    correction for edge locator `method` (seed 004 §4-5 and future-work item 3).

    Without a `model`: :func:`fit_roll_pitch_wgs84` with h* = 0 (the thesis' H_eq = 0 on WGS84). With one: started
    there (or at `initial`), each of `iterations` rounds predicts the pulse's edges from the climatology at the
    current estimate (:meth:`ClimatologyPulseModel.edge_windows`), takes the locator's h* on them
    (:func:`locator_horizon_heights_km`) and solves again with those heights. `options` go to the locator.
    """
    p = np.asarray(position_km, float)
    frame = np.asarray(orbit_to_frame, float)
    cones = [c for c, _ in CROSSINGS]
    if initial is None:
        roll, pitch = fit_roll_pitch_wgs84(phases_deg, cones, p, frame, 0.0, gamma_deg)
    else:
        roll, pitch = (float(v) for v in initial)
    if model is None:
        return roll, pitch
    for _ in range(int(iterations)):
        rot = frame @ body_to_orbit(roll, pitch)
        windows, peaks = model.edge_windows(p, rot, gamma_deg)
        heights = locator_horizon_heights_km(method, windows, peaks, p, rot, gamma_deg, **options)
        roll, pitch = fit_roll_pitch_wgs84(phases_deg, cones, p, frame, heights, gamma_deg, (roll, pitch))
    return roll, pitch
