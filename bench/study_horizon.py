"""Error budgets of the scanning Earth-horizon sensor by Monte Carlo (seed 004; its future-work items 4–8).

One simulation (:func:`simulate_horizon`) is one scan of the dual-cone sensor at a random attitude: the truth is
perturbed by one error source (or all of them), the four horizon crossings are located, and roll and pitch are solved
from them the way the sensor would, with the nominal model. Its roll and pitch errors are the simulation's outputs.

The chain (on a sphere of radius a = 6378.137 km, :mod:`calibration.horizon.scan`, but for the `oblate` factor):

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

Draws are made in one fixed order whatever the factor, so draw d is the same attitude and the same unit deviates at
every altitude and for every factor (common random numbers: the budget's rows differ by their factor only).

The atmosphere is not simulated yet (its model, calibration/horizon/atmosphere.py and corrections.py, is being
written beside this study): :func:`factor_problem` says so, and names a module when one is missing.
"""

from __future__ import annotations

import importlib.util

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

from .study_engine import StudyError, StudySpec

#: The error sources a budget row can switch on alone; "all" switches every one whose σ is non-zero.
FACTORS = ("altitude", "cone", "noise", "mount", "ifov", "oblate", "atmosphere")
BUDGET_ROWS = FACTORS + ("all",)
#: The library modules each factor needs beyond scan.py (the oblate Earth and the atmosphere are A1's and A2's).
FACTOR_MODULES = {"ifov": ("calibration.horizon.ifov",),
                  "oblate": ("calibration.horizon.oblate", "calibration.horizon.earth"),
                  "atmosphere": ("calibration.horizon.atmosphere", "calibration.horizon.pulse",
                                 "calibration.horizon.locator")}
#: Factors this module simulates today (the others are refused with :func:`factor_problem`'s words).
SIMULATED = ("altitude", "cone", "noise", "mount", "ifov", "oblate")
SOLVERS = ("least-squares", "steepest-descent", "free-rho", "closed-form")
#: The simulation's version (in the study's hash): bump when the physics of a simulation change.
VERSION = "1"

#: The defaults of `sunbench study horizon-errors`: seed 004 ref [16]'s 0.2° mounting and 10 km altitude
#: uncertainties, a 0.02° cone error, 20 µs of timing noise (0.0072° at 1 rev/s), the thesis' 2° IFOV.
DEFAULTS = {"altitude_error_km": 10.0, "cone_error_deg": 0.02, "noise_s": 2e-5, "mount_error_deg": 0.2,
            "ifov_deg": THESIS_IFOV_HALF_ANGLE_DEG, "gamma_deg": THESIS_GAMMA_DEG, "scan_rate_hz": THESIS_SCAN_RATE_HZ,
            "roll_range_deg": 10.0, "pitch_range_deg": 10.0, "solver": "least-squares",
            "inclination_deg": 97.4, "argument_of_latitude_deg": "random"}


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
    return on | ({"oblate"} if factor_problem("oblate") is None else set())


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
    inclination_deg and argument_of_latitude_deg (a number, or "random": drawn uniformly) for the WGS84 Earth.

    Returns roll_error_deg, pitch_error_deg (solved − true), nadir_error_deg (angle between the true and the solved
    nadir), rho_error_deg (the solver's ρ − the true sphere's), residual_rms (of eq. 2.7 at the solution; NaN for
    the closed form), solver_note (its warnings), the true roll and pitch, ρ of the sphere, the
    satellite's geocentric latitude on the WGS84 Earth (NaN on the sphere), and the deviations drawn (``drawn_…``:
    zero for the factors off).
    """
    p = {**DEFAULTS, **params}
    if p["solver"] not in SOLVERS:
        raise ValueError(f"no solver {p['solver']!r} ({', '.join(SOLVERS)})")
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
    if "oblate" in active:
        from calibration.horizon.ifov import locator_phase_bias_deg
        from calibration.horizon.oblate import crossing_phases_oblate, spherical_equivalent_radius_deg
        from calibration.horizon.orbit import body_to_frame

        where = p["argument_of_latitude_deg"]
        position, along = orbit_position(h, u["orbit"] if where == "random" else float(where),
                                         float(p["inclination_deg"]))
        latitude = float(np.degrees(np.arcsin(position[2] / np.linalg.norm(position))))
        sensor_to_frame = body_to_frame(position, along, roll, pitch) @ turn.as_matrix()
        rho_local = float(spherical_equivalent_radius_deg(position))
        crossings = [crossing_phases_oblate(position, sensor_to_frame, gamma + cone_error[k], cone)
                     for k, cone in enumerate((1, 2))]
        if alpha > 0:
            crossings = [np.add(c, locator_phase_bias_deg(n_sensor, rho_local, alpha, 0.5, gamma + cone_error[k],
                                                          k + 1)) for k, c in enumerate(crossings)]
    else:
        horizon = rho
        if alpha > 0:
            from calibration.horizon.ifov import level_separation_deg
            horizon = float(level_separation_deg(rho, alpha, 0.5))
        crossings = [crossing_phases_for_nadir(n_sensor, horizon, gamma + cone_error[k], cone)
                     for k, cone in enumerate((1, 2))]
    phases = []
    for cone, (out_, in_) in zip((1, 2), crossings):
        if not (np.isfinite(out_) and np.isfinite(in_)):
            raise ValueError(f"cone {cone} does not cross the horizon (ρ = {rho:.2f}° at {h:g} km, γ = {gamma:g}°, "
                             f"roll {roll:.2f}°, pitch {pitch:.2f}°)")
        phases.append((float(out_), float(in_)))
    noise_deg = on("noise", u["noise"] * float(p["noise_s"]) * 360.0 * float(p["scan_rate_hz"]))
    phases = np.mod(np.array(phases) + noise_deg.reshape(2, 2), 360.0)
    altitude_error = float(on("altitude", u["altitude"] * float(p["altitude_error_km"])))
    rho_believed = float(earth_angular_radius_deg(h + altitude_error, EQUATORIAL_RADIUS_KM))
    roll_s, pitch_s, rho_s, residual, note = solve(phases, rho_believed, gamma, str(p["solver"]))
    cos = float(np.clip(np.dot(nadir_in_body(roll_s, pitch_s), n_body), -1.0, 1.0))
    return {"roll_error_deg": roll_s - float(roll), "pitch_error_deg": pitch_s - float(pitch),
            "nadir_error_deg": float(np.degrees(np.arccos(cos))), "rho_error_deg": rho_s - rho,
            "residual_rms": residual, "solver_note": note,
            "roll_true_deg": float(roll), "pitch_true_deg": float(pitch), "rho_deg": rho, "latitude_deg": latitude,
            "drawn_altitude_error_km": altitude_error, "drawn_cone1_error_deg": float(cone_error[0]),
            "drawn_cone2_error_deg": float(cone_error[1]), "drawn_mount_x_deg": float(mount[0]),
            "drawn_mount_y_deg": float(mount[1]), "drawn_mount_z_deg": float(mount[2])}


def horizon_spec(*, altitudes_km=(400.0, 500.0, 700.0, 1000.0),
                 factors=("altitude", "cone", "noise", "mount", "ifov", "oblate", "all"), draws: int = 200,
                 seed: int = 0, chunk_size: int = 100, **options) -> StudySpec:
    """The spec of a horizon error budget: altitude × factor swept, `draws` attitudes each; any option of
    ``DEFAULTS`` given as a list is swept too, as a single value fixed."""
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise StudyError(f"unknown options {sorted(unknown)} (options: {', '.join(DEFAULTS)})")
    for f in factors:
        problem = factor_problem(f)
        if problem:
            raise FactorUnavailable(problem)
    sweep: dict = {"altitude_km": tuple(float(a) for a in altitudes_km), "factor": tuple(factors)}
    fixed: dict = {}
    for name, default in DEFAULTS.items():
        value = options.get(name, default)
        if isinstance(value, (list, tuple)):
            if len(value) > 1:
                sweep[name] = tuple(value)
                continue
            value = value[0]
        fixed[name] = value
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
