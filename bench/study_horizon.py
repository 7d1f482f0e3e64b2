"""Error budgets of the scanning Earth-horizon sensor by Monte Carlo (seed 004; its future-work items 4–8).

One simulation (:func:`simulate_horizon`) is one scan of the dual-cone sensor at a random attitude: the truth is
perturbed by one error source (or all of them), the four horizon crossings are located, and roll and pitch are solved
from them the way the sensor would, with the nominal model. Its roll and pitch errors are the simulation's outputs.

The chain (on a sphere of radius a = 6378.137 km, :mod:`calibration.horizon.scan`, but for `oblate` and `atmosphere`):

1. truth: roll φ and pitch θ drawn uniformly within ±`roll_range_deg`, ±`pitch_range_deg` (the sensor's range,
   seed 004 Table 1-1, is ±33° roll, ±17° pitch); the nadir in the spacecraft body is n_b (seed 004 eq. 2.6);
2. the sensor's mounting misalignment (`mount`: a small rotation, N(0, σ) about each body axis; seed 004 ref [16]:
   0.2°) turns n_b into the sensor's own frame; the spacecraft is told the sensor's attitude as its own;
3. each cone's true half-angle is γ + N(0, σ_γ) (`cone`);
4. the crossings: seed 004 eq. 2.7 (corrected) in closed form at the true ρ (eq. 2.3), or, with a finite IFOV
   (`ifov`), where the 50 % obscuration locator of eq. 2.1 fires (:func:`calibration.horizon.ifov.level_separation_deg`:
   the limb's curvature puts it inside the disc); on the WGS84 Earth (`oblate`) the satellite flies a circular
   97.4° orbit (MicroMAS-2A, seed 004 Table 3-1) at geodetic altitude h, at an argument of latitude drawn uniformly
   (or given), nadir-pointing on the orbit frame (geocentric nadir, :mod:`calibration.horizon.orbit`), and the cones
   cross the ellipsoid's horizon exactly (:func:`calibration.horizon.oblate.crossing_phases_oblate`, eqs. 2.10,
   2.17, 2.23), the IFOV's locator then moving each crossing as it does on the sphere of the same ρ
   (:func:`calibration.horizon.ifov.locator_phase_bias_deg`); timing noise N(0, σ_t) on each crossing time
   (`noise`), which the scan rate turns into phase (future-work item 6);
5. the solve, with the sensor's spherical model (as the thesis' cases B–D) and nominal γ, by the library's solvers
   (:mod:`calibration.horizon.attitude`): ``least-squares`` (eq. 2.7 for the four crossings, Levenberg–Marquardt)
   or ``steepest-descent`` (the thesis' method) with ρ' = asin(a/(a + h')) from the altitude the spacecraft
   believes, h' = h + N(0, σ_h) (`altitude`; ref [16]: 10 km); or with ρ solved from the crossings too, needing no
   altitude: ``free-rho`` (least squares over roll, pitch and ρ) and ``closed-form`` (the chords' centre and widths).

The atmosphere (`atmosphere`; seed 004 case D: WGS84, the IFOV, the 14–16 µm limb, §2-4-3, §4-5, Table 4-8) replaces
steps 4–5 by located edges and a WGS84 solve (:func:`atmosphere_crossings`, :func:`solve_atmosphere`):

a. the satellite on the WGS84 orbit of `oblate` (the atmosphere needs that Earth), the day `day_of_year` (default
   103, 12 April as the thesis, §3-5);
b. the truth's atmosphere, drawn per simulation: at each of the four crossings' tangent points and under the satellite
   (the pulse's brightest disc, which the thesis' locator normalises by) the climatology of its latitude
   (:func:`calibration.horizon.atmosphere.seasonal_profile`) plus one day's weather
   (:class:`~calibration.horizon.atmosphere.WeatherModel`, drawn independently per crossing: `weather` is
   ``ordinary`` (:data:`~calibration.horizon.atmosphere.ORDINARY_WEATHER`), ``cold-pool``
   (:data:`~calibration.horizon.atmosphere.POLAR_COLD_POOL_WEATHER`) or ``none`` (the climatology itself)), seen
   through another band model than the correction's (:data:`~calibration.horizon.atmosphere.CO2_BAND_SEVEN`, its
   strength log-normal with σ `band_error`, default 5 %) — as tests/calibration/horizon/test_atmosphere_robustness.py;
c. the pulse's four edge windows through the top-hat IFOV of half-angle `ifov_deg`, sampled every `sample_s` (the
   thesis' case D: 10⁻³ s) on the scan's clock (:func:`calibration.horizon.corrections.simulate_edge_windows`), each
   cone at its own true half-angle, in the sensor's turned axes;
d. the crossings located by `locator` (:func:`calibration.horizon.locator.locate_edge`: ``peak-threshold`` is the
   thesis' eq. 2.1 normalised by the pulse's peak; ``local-threshold``, ``local-integrated`` (eq. 2.2, C2 = 1°),
   ``inflection``, ``two-level`` are blind to the edge's radiance scale), then timing noise;
e. the solve on WGS84 with the satellite's position as the spacecraft believes it (its altitude off by the
   `altitude` draw), nominal γ (:func:`calibration.horizon.corrections.fit_roll_pitch_wgs84`: each crossing ray
   tangent to the ellipsoid grown by h*): `atmosphere_correction` ``none`` is the thesis' case D, H_eq = h* = 0;
   ``climatology`` predicts each edge from the climatology (the day and the crossing's latitude, the 5-sub-band model;
   it does not know the weather) at the uncorrected solution, runs the same locator on the prediction and solves
   again with those h* (:class:`~calibration.horizon.corrections.ClimatologyPulseModel`,
   :func:`~calibration.horizon.corrections.locator_horizon_heights_km`; one round: h* hardly moves with the
   attitude). Wherever the atmosphere is simulated — its row, and `all` — this WGS84 solve is the one used and
   `solver` does not apply (the row's ``solution`` says which solve ran); `all` thus solves the oblateness away.

Draws are made in one fixed order whatever the factor, so draw d is the same attitude and the same unit deviates at
every altitude and for every factor (common random numbers: the budget's rows differ by their factor only); the
weather and the band are drawn from their own stream of the seed, so draw d is the same weather for every locator,
correction and weather model (``cold-pool`` adds its pools to ``ordinary``'s anomalies).
"""

from __future__ import annotations

import importlib.util
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from calibration.horizon.scan import (
    EQUATORIAL_RADIUS_KM,
    THESIS_GAMMA_DEG,
    THESIS_IFOV_HALF_ANGLE_DEG,
    THESIS_SCAN_RATE_HZ,
    crossing_phases_for_nadir,
    earth_angular_radius_deg,
    nadir_in_body,
)

from .study_engine import StudyError, StudySpec, sweep_options

#: The error sources a budget row can switch on alone; "all" switches every one whose σ is non-zero.
FACTORS = ("altitude", "cone", "noise", "mount", "ifov", "oblate", "atmosphere")
BUDGET_ROWS = FACTORS + ("all",)
#: The library modules each factor needs beyond scan.py.
FACTOR_MODULES = {"ifov": ("calibration.horizon.ifov",),
                  "oblate": ("calibration.horizon.oblate", "calibration.horizon.earth"),
                  "atmosphere": ("calibration.horizon.atmosphere", "calibration.horizon.pulse",
                                 "calibration.horizon.locator", "calibration.horizon.corrections")}
#: Factors this module simulates (others would be refused with :func:`factor_problem`'s words).
SIMULATED = ("altitude", "cone", "noise", "mount", "ifov", "oblate", "atmosphere")
SOLVERS = ("least-squares", "steepest-descent", "free-rho", "closed-form")
#: The edge locators of the atmosphere factor (:func:`calibration.horizon.locator.locate_edge`'s methods).
LOCATORS = ("peak-threshold", "local-threshold", "local-integrated", "inflection", "two-level")
#: Their options: eq. 2.2's C2 = 1° of phase for the integrated locator (as test_atmosphere_robustness.py).
LOCATOR_OPTIONS = {"local-integrated": {"c2_deg": 1.0}}
ATMOSPHERE_CORRECTIONS = ("none", "climatology")
WEATHERS = ("ordinary", "cold-pool", "none")
#: The simulation's version (in the study's hash): bump when the physics of a simulation change.
VERSION = "2"

#: The defaults of `sunbench study horizon-errors`: seed 004 ref [16]'s 0.2° mounting and 10 km altitude
#: uncertainties, a 0.02° cone error, 20 µs of timing noise (0.0072° at 1 rev/s), the thesis' 2° IFOV; for the
#: atmosphere the thesis' locator and case D's 10⁻³ s samples, ordinary weather on 12 April, no correction.
DEFAULTS = {"altitude_error_km": 10.0, "cone_error_deg": 0.02, "noise_s": 2e-5, "mount_error_deg": 0.2,
            "ifov_deg": THESIS_IFOV_HALF_ANGLE_DEG, "gamma_deg": THESIS_GAMMA_DEG, "scan_rate_hz": THESIS_SCAN_RATE_HZ,
            "roll_range_deg": 10.0, "pitch_range_deg": 10.0, "solver": "least-squares",
            "inclination_deg": 97.4, "argument_of_latitude_deg": "random",
            "locator": "peak-threshold", "atmosphere_correction": "none", "weather": "ordinary", "band_error": 0.05,
            "day_of_year": 103.0, "sample_s": 1e-3}
#: The options that only the atmosphere uses (the other rows ignore them).
ATMOSPHERE_OPTIONS = ("locator", "atmosphere_correction", "weather", "band_error", "day_of_year", "sample_s")
#: Each option's allowed words (a bad one is refused before the study starts).
CHOICES = {"solver": SOLVERS, "locator": LOCATORS, "atmosphere_correction": ATMOSPHERE_CORRECTIONS,
           "weather": WEATHERS}


class FactorUnavailable(StudyError):
    """A factor whose model is not in the library yet."""


def factor_problem(factor: str) -> str | None:
    """Why `factor` cannot be simulated here (None when it can)."""
    if factor not in BUDGET_ROWS:
        return f"no factor {factor!r} (factors: {', '.join(BUDGET_ROWS)})"
    missing = [m for m in FACTOR_MODULES.get(factor, ()) if importlib.util.find_spec(m) is None]
    if missing:
        return f"the {factor} factor needs {', '.join(missing)}, which is not in the library yet"
    if factor not in SIMULATED and factor != "all":
        return (f"the {factor} factor is not wired into the study yet (its model is in the library: "
                f"{', '.join(FACTOR_MODULES[factor])})")
    return None


def solve(phases, rho_deg: float, gamma_deg: float, solver: str) -> tuple[float, float, float, float, str]:
    """Roll, pitch and ρ [°] from ``((out₁, in₁), (out₂, in₂))`` by `solver` (:data:`SOLVERS`; ρ given or solved,
    module docstring), the RMS of eq. 2.7's residuals at the solution (cos units) and the solver's warnings."""
    from calibration.horizon.attitude import solve_spherical, spherical_closed_form

    out, inn = phases[:, 0], phases[:, 1]
    if solver == "closed-form":
        roll, pitch, rho = spherical_closed_form(out, inn, gamma_deg)
        return roll, pitch, rho, float("nan"), ""
    method = "steepest-descent" if solver == "steepest-descent" else "least-squares"
    fit = solve_spherical(out, inn, gamma_deg, None if solver == "free-rho" else rho_deg, method=method)
    return (fit.roll_deg, fit.pitch_deg, float(fit.rho_deg), float(np.sqrt(np.mean(np.square(fit.residuals)))),
            "; ".join(fit.warnings))


# -- one simulation ---------------------------------------------------------------------------------------------------
def _unit_draws(rng: np.random.Generator) -> dict:
    """Every random number of one simulation, in one fixed order (common random numbers across factors)."""
    return {"attitude": rng.uniform(-1.0, 1.0, 2), "altitude": rng.standard_normal(), "cone": rng.standard_normal(2),
            "mount": rng.standard_normal(3), "noise": rng.standard_normal(4), "orbit": rng.uniform(0.0, 360.0)}


def _active(factor: str, params: dict) -> set[str]:
    problem = factor_problem(factor)
    if problem:
        raise FactorUnavailable(problem)
    if factor != "all":
        return {factor}
    sigma = {"altitude": "altitude_error_km", "cone": "cone_error_deg", "noise": "noise_s", "mount": "mount_error_deg",
             "ifov": "ifov_deg"}
    on = {f for f, key in sigma.items() if float(params.get(key, 0.0)) > 0 and factor_problem(f) is None}
    return on | {f for f in ("oblate", "atmosphere") if factor_problem(f) is None}


def orbit_position(altitude_km: float, argument_of_latitude_deg: float, inclination_deg: float):
    """Position [km] and velocity direction of a satellite on a circular orbit of inclination i (ascending node on
    the x axis) at argument of latitude u, at geodetic altitude `altitude_km` above WGS84 (seed 004 Table 3-1's
    MicroMAS-2A orbit: i = 97.4°)."""
    from calibration.horizon.earth import geodetic_height_km, surface_radius_km

    u, i = np.radians(argument_of_latitude_deg), np.radians(inclination_deg)
    up = np.array([np.cos(u), np.sin(u) * np.cos(i), np.sin(u) * np.sin(i)])
    along = np.array([-np.sin(u), np.cos(u) * np.cos(i), np.cos(u) * np.sin(i)])
    radius = float(surface_radius_km(np.degrees(np.arcsin(up[2])))) + altitude_km
    for _ in range(3):  # the geocentric radius whose geodetic height is `altitude_km` (the normals differ ≤ 0.2°)
        radius += altitude_km - float(geodetic_height_km(radius * up))
    return radius * up, along


def simulate_horizon(params: dict, seed: int) -> dict:
    """One scan at a random attitude with the error source(s) of ``params["factor"]``; the module docstring has the
    chain. Parameters (``DEFAULTS`` fill the missing ones): altitude_km, factor, altitude_error_km, cone_error_deg,
    noise_s, mount_error_deg, ifov_deg, gamma_deg, scan_rate_hz, roll_range_deg, pitch_range_deg, solver,
    inclination_deg and argument_of_latitude_deg (a number, or "random": drawn uniformly) for the WGS84 Earth; for
    the atmosphere locator, atmosphere_correction, weather, band_error, day_of_year and sample_s [s].

    Returns roll_error_deg, pitch_error_deg (solved − true), nadir_error_deg (angle between the true and the solved
    nadir), rho_error_deg (the solver's ρ − the true sphere's; NaN for the WGS84 solve), residual_rms (of eq. 2.7 at
    the solution; NaN for the closed form and the WGS84 solve), solver_note (its warnings), solution (the solve that
    ran: the solver's name, or ``wgs84, h* = 0`` / ``wgs84, h* of the climatology``), with the atmosphere the mean
    true horizon height where the locator fired (horizon_true_km), the mean h* the solve used (horizon_used_km) and
    the RMS of their difference over the four crossings (horizon_miss_km) [km] (NaN without the atmosphere), the true
    roll and pitch, ρ of the sphere, the satellite's geocentric latitude on the WGS84 Earth (NaN on the sphere), and
    the deviations drawn (``drawn_…``: zero for the factors off).
    """
    p = {**DEFAULTS, **params}
    for name, allowed in CHOICES.items():
        if p[name] not in allowed:
            raise ValueError(f"no {name.replace('_', ' ')} {p[name]!r} ({', '.join(allowed)})")
    active = _active(str(p["factor"]), p)
    u = _unit_draws(np.random.default_rng(seed))
    on = lambda name, value: value if name in active else 0.0 * value  # noqa: E731 - the factor's switch
    h, gamma = float(p["altitude_km"]), float(p["gamma_deg"])
    roll, pitch = u["attitude"] * (float(p["roll_range_deg"]), float(p["pitch_range_deg"]))
    n_body = nadir_in_body(roll, pitch)
    mount = on("mount", u["mount"] * float(p["mount_error_deg"]))
    turn = Rotation.from_rotvec(np.radians(mount))  # the sensor's axes in the body, turned by `mount`
    n_sensor = turn.inv().apply(n_body)
    cone_error = on("cone", u["cone"] * float(p["cone_error_deg"]))
    rho = float(earth_angular_radius_deg(h, EQUATORIAL_RADIUS_KM))
    alpha = float(p["ifov_deg"]) if "ifov" in active else 0.0
    latitude = float("nan")
    noise_deg = on("noise", u["noise"] * float(p["noise_s"]) * 360.0 * float(p["scan_rate_hz"]))
    altitude_error = float(on("altitude", u["altitude"] * float(p["altitude_error_km"])))
    horizon = {"horizon_true_km": float("nan"), "horizon_used_km": float("nan"), "horizon_miss_km": float("nan")}
    if "oblate" in active or "atmosphere" in active:
        where = p["argument_of_latitude_deg"]
        position, along = orbit_position(h, u["orbit"] if where == "random" else float(where),
                                         float(p["inclination_deg"]))
        latitude = float(np.degrees(np.arcsin(position[2] / np.linalg.norm(position))))
    if "atmosphere" in active:
        located, true_heights = atmosphere_crossings(p, seed, position, along, float(roll), float(pitch), mount,
                                                     cone_error)
        phases = np.mod(located + noise_deg, 360.0)
        # the altitude the spacecraft believes, along the radius (it is within 0.2° of the ellipsoid's normal)
        believed = position * (1.0 + altitude_error / float(np.linalg.norm(position)))
        roll_s, pitch_s, used = solve_atmosphere(phases, believed, along, p)
        rho_s, residual, note = float("nan"), float("nan"), ""
        solution = f"wgs84, h* {'= 0' if p['atmosphere_correction'] == 'none' else 'of the climatology'}"
        horizon = {"horizon_true_km": float(np.mean(true_heights)), "horizon_used_km": float(np.mean(used)),
                   "horizon_miss_km": float(np.sqrt(np.mean(np.square(true_heights - used))))}
    else:
        if "oblate" in active:
            from calibration.horizon.ifov import locator_phase_bias_deg
            from calibration.horizon.oblate import crossing_phases_oblate, spherical_equivalent_radius_deg
            from calibration.horizon.orbit import body_to_frame

            sensor_to_frame = body_to_frame(position, along, roll, pitch) @ turn.as_matrix()
            rho_local = float(spherical_equivalent_radius_deg(position))
            crossings = [crossing_phases_oblate(position, sensor_to_frame, gamma + cone_error[k], cone)
                         for k, cone in enumerate((1, 2))]
            if alpha > 0:
                crossings = [np.add(c, locator_phase_bias_deg(n_sensor, rho_local, alpha, 0.5,
                                                              gamma + cone_error[k], k + 1))
                             for k, c in enumerate(crossings)]
        else:
            edge = rho
            if alpha > 0:
                from calibration.horizon.ifov import level_separation_deg
                edge = float(level_separation_deg(rho, alpha, 0.5))
            crossings = [crossing_phases_for_nadir(n_sensor, edge, gamma + cone_error[k], cone)
                         for k, cone in enumerate((1, 2))]
        phases = []
        for cone, (out_, in_) in zip((1, 2), crossings):
            if not (np.isfinite(out_) and np.isfinite(in_)):
                raise ValueError(f"cone {cone} does not cross the horizon (ρ = {rho:.2f}° at {h:g} km, γ = "
                                 f"{gamma:g}°, roll {roll:.2f}°, pitch {pitch:.2f}°)")
            phases.append((float(out_), float(in_)))
        phases = np.mod(np.array(phases) + noise_deg.reshape(2, 2), 360.0)
        rho_believed = float(earth_angular_radius_deg(h + altitude_error, EQUATORIAL_RADIUS_KM))
        roll_s, pitch_s, rho_s, residual, note = solve(phases, rho_believed, gamma, str(p["solver"]))
        solution = str(p["solver"])
    cos = float(np.clip(np.dot(nadir_in_body(roll_s, pitch_s), n_body), -1.0, 1.0))
    return {"roll_error_deg": roll_s - float(roll), "pitch_error_deg": pitch_s - float(pitch),
            "nadir_error_deg": float(np.degrees(np.arccos(cos))), "rho_error_deg": rho_s - rho,
            "residual_rms": residual, "solver_note": note, "solution": solution, **horizon,
            "roll_true_deg": float(roll), "pitch_true_deg": float(pitch), "rho_deg": rho, "latitude_deg": latitude,
            "drawn_altitude_error_km": altitude_error, "drawn_cone1_error_deg": float(cone_error[0]),
            "drawn_cone2_error_deg": float(cone_error[1]), "drawn_mount_x_deg": float(mount[0]),
            "drawn_mount_y_deg": float(mount[1]), "drawn_mount_z_deg": float(mount[2])}


# -- the atmosphere (module docstring, steps a–e) ----------------------------------------------------------------------
def _weather_model(name: str):
    from calibration.horizon import atmosphere as A

    return {"ordinary": A.ORDINARY_WEATHER, "cold-pool": A.POLAR_COLD_POOL_WEATHER, "none": None}[name]


def sample_step_deg(params: dict) -> float:
    """The pulse's sample step in phase [°]: 360° × scan rate × `sample_s` (0.36° for the thesis' case D)."""
    return 360.0 * float(params["scan_rate_hz"]) * float(params["sample_s"])


@lru_cache(maxsize=8)
def climatology_model(day_of_year: float):
    """The correction's knowledge for a day (:class:`calibration.horizon.corrections.ClimatologyPulseModel`: the
    climatology per degree of latitude and the 5-sub-band model), one per worker process: its radiance tables are
    computed once per latitude and kept for every later simulation."""
    from calibration.horizon.corrections import ClimatologyPulseModel

    return ClimatologyPulseModel(float(day_of_year))


@lru_cache(maxsize=128)
def _truth_windows(seed: int, position: tuple, along: tuple, roll: float, pitch: float, mount: tuple, gammas: tuple,
                   half_angle_deg: float, step_deg: float, weather: str, band_error: float, day_of_year: float):
    """The truth's four edge windows and each cone's peak (steps b–c), and the sensor → frame rotation; kept per
    process so the settings that share a draw's truth (locators, corrections) simulate it once."""
    from calibration.horizon import atmosphere as A
    from calibration.horizon import corrections as C
    from calibration.horizon.orbit import body_to_frame

    p = np.asarray(position, float)
    rot = body_to_frame(p, np.asarray(along, float), roll, pitch) @ Rotation.from_rotvec(np.radians(mount)).as_matrix()
    rng = np.random.default_rng([int(seed), 1])  # the weather's own stream: the other draws stay as they were
    band = A.BandModel(A.CO2_BAND_SEVEN.weights, A.CO2_BAND_SEVEN.unit_depth_heights_km,
                       strength=float(np.exp(float(band_error) * rng.standard_normal())))
    model = _weather_model(weather)

    def truth(latitude):
        base = A.seasonal_profile(float(latitude), day_of_year)
        prof = base if model is None else A.weather_profile(base, float(latitude), rng, model)
        return A.radiance_table(prof, band, step_km=0.5, layer_km=1.0)  # its own numerics: 1-km layers

    cones = [c for c, _ in C.CROSSINGS]
    latitudes = [C.crossing_tangent_latitudes_deg(p, rot, gammas[cone - 1])[1][k] for k, cone in enumerate(cones)]
    crossing_tables = [truth(lat) for lat in latitudes]
    disc = truth(C.sub_satellite_latitude_deg(p))
    windows, peaks = [None] * 4, {}
    for gamma in sorted(set(gammas)):
        ws, pk = C.simulate_edge_windows(p, rot, crossing_tables, disc, gamma, half_angle_deg, step_deg)
        for k, cone in enumerate(cones):
            if gammas[cone - 1] == gamma:
                windows[k], peaks[cone] = ws[k], pk[cone]
    return tuple(windows), peaks, rot


def atmosphere_crossings(params: dict, seed: int, position, along, roll: float, pitch: float, mount,
                         cone_error) -> tuple[np.ndarray, np.ndarray]:
    """The four crossing phases [°] (cone 1 out, in, cone 2 out, in) that `params["locator"]` finds on the pulse of
    the truth's atmosphere (module docstring, steps a–d; seed 004 §2-4-3, eqs. 2.1–2.2), and the true tangent height
    [km] of the boresight at each (where the locator fired: the crossing's true h*)."""
    from calibration.horizon import corrections as C
    from calibration.horizon.pulse import tangent_height_scaled_km
    from calibration.horizon.scan import scan_vector

    alpha = float(params["ifov_deg"])
    if not alpha > 0:
        raise ValueError(f"the atmosphere's pulse needs a finite IFOV: ifov_deg must be positive, got {alpha!r}")
    gamma = float(params["gamma_deg"])
    gammas = (gamma + float(cone_error[0]), gamma + float(cone_error[1]))
    windows, peaks, rot = _truth_windows(
        int(seed), tuple(np.asarray(position, float)), tuple(np.asarray(along, float)), float(roll), float(pitch),
        tuple(float(m) for m in mount), gammas, alpha, sample_step_deg(params), str(params["weather"]),
        float(params["band_error"]), float(params["day_of_year"]))
    locator = str(params["locator"])
    phases = C.locate_windows(locator, windows, peaks, **LOCATOR_OPTIONS.get(locator, {}))
    dirs = np.stack([scan_vector(ph, gammas[w.cone - 1], w.cone) for ph, w in zip(phases, windows)]) @ rot.T
    return phases, tangent_height_scaled_km(np.asarray(position, float), dirs)


def solve_atmosphere(phases, position, along, params: dict) -> tuple[float, float, np.ndarray]:
    """Roll, pitch [°] and the horizon heights h* [km] used, from the four located crossings on WGS84 with the
    satellite at `position` (as the spacecraft believes it), nominal γ (module docstring, step e; seed 004 §4-5):
    h* = 0 (``atmosphere_correction`` ``none``, the thesis' case D) or each crossing's h* predicted from the
    climatology by the same locator at the uncorrected solution (``climatology``)."""
    from calibration.horizon import corrections as C
    from calibration.horizon.orbit import orbit_frame
    from calibration.horizon.scan import body_to_orbit

    gamma, p = float(params["gamma_deg"]), np.asarray(position, float)
    frame = orbit_frame(p, np.asarray(along, float))
    cones = [c for c, _ in C.CROSSINGS]
    roll, pitch = C.fit_roll_pitch_wgs84(phases, cones, p, frame, 0.0, gamma)
    if params["atmosphere_correction"] == "none":
        return roll, pitch, np.zeros(len(cones))
    locator = str(params["locator"])
    options = LOCATOR_OPTIONS.get(locator, {})
    rot = frame @ body_to_orbit(roll, pitch)
    predicted, peaks = climatology_model(float(params["day_of_year"])).edge_windows(
        p, rot, gamma, half_angle_deg=float(params["ifov_deg"]), step_deg=sample_step_deg(params))
    heights = C.locator_horizon_heights_km(locator, predicted, peaks, p, rot, gamma, **options)
    roll, pitch = C.fit_roll_pitch_wgs84(phases, cones, p, frame, heights, gamma, (roll, pitch))
    return roll, pitch, heights


def horizon_spec(*, altitudes_km=(400.0, 500.0, 700.0, 1000.0),
                 factors=("altitude", "cone", "noise", "mount", "ifov", "oblate", "atmosphere", "all"),
                 draws: int = 200, seed: int = 0, chunk_size: int = 100, **options) -> StudySpec:
    """The spec of a horizon error budget: altitude × factor swept, `draws` attitudes each; any option of
    ``DEFAULTS`` given as a list is swept too, as a single value fixed."""
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise StudyError(f"unknown options {sorted(unknown)} (options: {', '.join(DEFAULTS)})")
    for f in factors:
        problem = factor_problem(f)
        if problem:
            raise FactorUnavailable(problem)
    for name, allowed in CHOICES.items():
        value = options.get(name, DEFAULTS[name])
        for v in value if isinstance(value, (list, tuple)) else (value,):
            if v not in allowed:
                raise StudyError(f"no {name.replace('_', ' ')} {v!r} ({', '.join(allowed)})")
    sweep, fixed = sweep_options(DEFAULTS, options, {"altitude_km": tuple(float(a) for a in altitudes_km),
                                                     "factor": tuple(factors)})
    return StudySpec("horizon-errors", "bench.study_horizon:simulate_horizon", sweep, fixed, draws=draws, seed=seed,
                     chunk_size=chunk_size, version=VERSION)


def write_horizon_plot(table, summary, path):
    """RMS roll and pitch error against altitude, one line per factor (and per other swept option), with the 95th
    percentile of |error| dashed (plotly HTML)."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from .field_plots import write_figure

    others = [c for c in summary.columns if c not in ("altitude_km", "output", "simulations", "errors", "n", "failed",
                                                       "mean", "sd", "mean_abs", "rms", "p50_abs", "p95_abs",
                                                       "p99_abs", "max_abs")]
    fig = make_subplots(rows=1, cols=3, subplot_titles=["roll error [°]", "pitch error [°]", "nadir error [°]"])
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]
    for col, output in enumerate(("roll_error_deg", "pitch_error_deg", "nadir_error_deg"), start=1):
        part = summary[summary["output"] == output]
        for i, (key, g) in enumerate(part.groupby(others, sort=False)):
            label = ", ".join(str(v) for v in (key if isinstance(key, tuple) else (key,)))
            colour = colours[i % len(colours)]
            g = g.sort_values("altitude_km")
            fig.add_trace(go.Scatter(x=g["altitude_km"], y=g["rms"], mode="lines+markers", name=f"{label} RMS",
                                     line={"color": colour}, legendgroup=label, showlegend=col == 1), row=1, col=col)
            fig.add_trace(go.Scatter(x=g["altitude_km"], y=g["p95_abs"], mode="lines", name=f"{label} 95 %",
                                     line={"color": colour, "dash": "dash"}, legendgroup=label, showlegend=False),
                          row=1, col=col)
        fig.update_xaxes(title_text="altitude [km]", row=1, col=col)
        fig.update_yaxes(type="log", row=1, col=col)
    fig.update_layout(height=500, template="plotly_white",
                      title="Horizon sensor error budget (seed 004): RMS (solid) and 95 % of |error| (dashed)")
    return write_figure(fig, path)
