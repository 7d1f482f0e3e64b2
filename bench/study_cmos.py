"""Plan density against CMOS sun-sensor accuracy, by Monte Carlo over simulated sensors (seed 003's procedure).

One simulation (:func:`simulate_cmos`) is one flight sensor calibrated with one plan:

1. the sensor: :func:`drivers.sim.world.fleet_sensor` draws a serial's build (pinhole offset, air gap, cover glass,
   die tilt and rotation, a slightly non-round hole) around the simulator's default sensor; draw d's serial is the
   same at every plan, so every plan calibrates the same sensors;
2. the bench run: the plan's directions (seed 003 §4.2's grid: `azimuths` azimuths, `rings` zenith rings from 0 to
   `zenith_max_deg`, `repeats` frames each, and a centre stage of `repeats` + 1 frames at every azimuth — seed 003's
   5 for its 4), spot centres from the simulator's own ray trace (:func:`drivers.sim.raytrace.trace_bench_frames`,
   never the fit's model) with Gaussian centroid noise of `noise_px`; the bench is ideal (the table sets the body
   direction exactly), so what is scored is the plan and the method, not the bench geometry;
3. the fits: every method of :data:`calibration.models.METHODS` on the repeats' means (as seed 003 §4.3 does);
4. the score: `check_points` directions drawn uniformly over the field (solid angle, zenith up to `zenith_max_deg`),
   never on the plan, their noise-free spots through each calibration: vector error RMS, 95th percentile and max
   (seed 003 eq. 13). A method that cannot be fitted from the plan (a 6th-order θ(r) from fewer than 7 rings, a
   sector model with fewer azimuths than sectors) says why in its ``<method>.error`` column.
"""

from __future__ import annotations

import numpy as np

from calibration.data import BenchData
from calibration.errors import CalibrationError
from calibration.geometry import angular_error_deg
from calibration.models import METHODS
from calibration.procedure import SEED003_ZENITH_MAX_DEG
from calibration.synthetic import seed003_grid
from drivers.sim.raytrace import trace_bench_frames, trace_chief_ray
from drivers.sim.world import SensorTruth, fleet_sensor

from .study_engine import StudyError, StudySpec, sweep_options

VERSION = "1"
#: `sunbench study cmos-plan`'s defaults: seed 003's 8 × 7 × 4 plan among sparser and denser ones.
DEFAULTS = {"noise_px": 0.02, "zenith_max_deg": SEED003_ZENITH_MAX_DEG, "check_points": 400}


def plan_directions(azimuths: int, rings: int, repeats: int, zenith_max_deg: float = SEED003_ZENITH_MAX_DEG):
    """The bench directions of a seed 003-style plan, in measurement order: (zenith_deg, azimuth_deg, repeat).

    `azimuths` equally spaced azimuths, `rings` zenith-stage angles from 0 to `zenith_max_deg` (both included),
    `repeats` frames at each, after a centre stage of `repeats` + 1 frames at every azimuth at normal incidence
    (seed 003 §4.2: 8 × 7 × 4 and 5 at the centre; :func:`calibration.synthetic.seed003_grid`).
    """
    if azimuths < 1 or rings < 2 or repeats < 1:
        raise ValueError(f"a plan needs ≥ 1 azimuth, ≥ 2 rings and ≥ 1 repeat, got {azimuths} × {rings} × {repeats}")
    return seed003_grid(azimuth_step_deg=360.0 / azimuths, zenith_max_deg=zenith_max_deg,
                        zenith_step_deg=zenith_max_deg / (rings - 1), repeats=repeats, centre_repeats=repeats + 1)


def check_directions(n: int, zenith_max_deg: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """`n` directions uniform in solid angle over the field (zenith ≤ `zenith_max_deg`) [°]."""
    cos_z = rng.uniform(np.cos(np.radians(zenith_max_deg)), 1.0, n)
    return np.degrees(np.arccos(cos_z)), rng.uniform(0.0, 360.0, n)


def sensor_for_draw(seed: int) -> SensorTruth:
    """The flight sensor of a draw: a serial named after its seed, built by :func:`fleet_sensor`."""
    return fleet_sensor(SensorTruth(), f"MC-{seed:010d}")


def _on_detector(x, y, truth: SensorTruth) -> np.ndarray:
    d = truth.design
    return np.isfinite(x) & np.isfinite(y) & (x >= 0) & (y >= 0) & (x <= d.width_px - 1) & (y <= d.height_px - 1)


def simulate_cmos(params: dict, seed: int) -> dict:
    """One sensor calibrated with one plan and scored held out (module docstring). Parameters: azimuths, rings,
    repeats (the plan), noise_px, zenith_max_deg, check_points. Returns frames (the plan's size), and per method
    ``<method>.rms_deg``, ``.p95_deg``, ``.max_deg`` (the vector error at the check directions [°]) and
    ``.error`` (why the method could not be fitted, else empty)."""
    p = {**DEFAULTS, **params}
    azimuths, rings, repeats = int(p["azimuths"]), int(p["rings"]), int(p["repeats"])
    zenith_max = float(p["zenith_max_deg"])
    truth = sensor_for_draw(seed)
    rng = np.random.default_rng(seed)
    zenith, azimuth, repeat = plan_directions(azimuths, rings, repeats, zenith_max)
    x, y = trace_bench_frames(zenith, azimuth, truth.optics, noise_px=float(p["noise_px"]), rng=rng)
    keep = _on_detector(x, y, truth)
    data = BenchData(zenith[keep], azimuth[keep], x[keep], y[keep], repeat=repeat[keep],
                     sensor_id=truth.serial).direction_means()
    z_check, a_check = check_directions(int(p["check_points"]), zenith_max, rng)
    x_check, y_check = trace_chief_ray(z_check, a_check, truth.optics)
    out: dict = {"frames": int(keep.sum()), "directions": len(data)}
    for method, model in METHODS.items():
        try:
            calibration = model.fit(data)
            z, a = calibration.apply(x_check, y_check)
            error = angular_error_deg(z_check, a_check, z, a)
            if not np.all(np.isfinite(error)):
                raise CalibrationError(f"no direction for {int((~np.isfinite(error)).sum())} of {error.size} "
                                       "check points")
            out |= {f"{method}.rms_deg": float(np.sqrt(np.mean(error ** 2))),
                    f"{method}.p95_deg": float(np.percentile(error, 95)), f"{method}.max_deg": float(error.max()),
                    f"{method}.error": ""}
        except (CalibrationError, ValueError, np.linalg.LinAlgError) as exc:
            out |= {f"{method}.rms_deg": float("nan"), f"{method}.p95_deg": float("nan"),
                    f"{method}.max_deg": float("nan"), f"{method}.error": f"{type(exc).__name__}: {exc}"}
    return out


def cmos_spec(*, azimuths=(4, 8, 16), rings=(4, 7, 13), repeats=(1, 4), draws: int = 20, seed: int = 0,
              chunk_size: int = 4, **options) -> StudySpec:
    """The spec of a plan study: azimuths × rings × repeats swept, `draws` sensors each; ``DEFAULTS``' options given
    as a list of several values are swept too."""
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise StudyError(f"unknown options {sorted(unknown)} (options: {', '.join(DEFAULTS)})")
    for name, values, least in (("azimuths", azimuths, 1), ("rings", rings, 2), ("repeats", repeats, 1)):
        bad = [v for v in values if int(v) != v or v < least]
        if bad:
            raise StudyError(f"`{name}` must be whole numbers ≥ {least}, got {bad}")
    sweep, fixed = sweep_options(DEFAULTS, options, {"azimuths": tuple(int(v) for v in azimuths),
                                                     "rings": tuple(int(v) for v in rings),
                                                     "repeats": tuple(int(v) for v in repeats)})
    return StudySpec("cmos-plan", "bench.study_cmos:simulate_cmos", sweep, fixed, draws=draws, seed=seed,
                     chunk_size=chunk_size, version=VERSION)


def plan_label(row) -> str:
    return f"{int(row['azimuths'])}×{int(row['rings'])}×{int(row['repeats'])}"


def plan_table(table):
    """Per plan (and other swept option) and method: the plan's frames, the mean over sensors of the held-out
    RMS, the 95th percentile over sensors of the max error [°], and how many sensors the method failed on."""
    import pandas as pd

    methods = list(METHODS)
    keys = [c for c in ("azimuths", "rings", "repeats", "noise_px", "zenith_max_deg", "check_points")
            if c in table.columns and (c in ("azimuths", "rings", "repeats") or table[c].nunique() > 1)]
    rows = []
    for key, g in table.groupby(keys, sort=True):
        row = dict(zip(keys, key if isinstance(key, tuple) else (key,)))
        row["frames"] = int(g["frames"].median()) if "frames" in g else 0
        row["sensors"] = len(g)
        for m in methods:
            rms = g.get(f"{m}.rms_deg", pd.Series(dtype=float)).to_numpy(float)
            mx = g.get(f"{m}.max_deg", pd.Series(dtype=float)).to_numpy(float)
            ok = np.isfinite(rms)
            row[f"{m}.mean_rms_deg"] = float(rms[ok].mean()) if ok.any() else float("nan")
            row[f"{m}.p95_max_deg"] = float(np.percentile(mx[ok], 95)) if ok.any() else float("nan")
            row[f"{m}.failed"] = int((~ok).sum())
        rows.append(row)
    return pd.DataFrame(rows)


def write_cmos_plot(table, summary, path):
    """Held-out accuracy against the plan's frames, one line per method: the mean over sensors of the RMS vector
    error (solid) and the 95th percentile over sensors of the max error (dashed), each point a plan (plotly)."""
    import plotly.graph_objects as go

    from .field_plots import write_figure

    plans = plan_table(table).sort_values("frames")
    labels = [plan_label(r) for _, r in plans.iterrows()]
    fig = go.Figure()
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd"]
    for i, m in enumerate(METHODS):
        colour = colours[i % len(colours)]
        fig.add_trace(go.Scatter(x=plans["frames"], y=plans[f"{m}.mean_rms_deg"], mode="lines+markers", name=m,
                                 text=labels, hovertemplate="%{text}: %{y:.4f}°", line={"color": colour},
                                 legendgroup=m))
        fig.add_trace(go.Scatter(x=plans["frames"], y=plans[f"{m}.p95_max_deg"], mode="lines", name=f"{m} 95 % max",
                                 text=labels, hovertemplate="%{text}: %{y:.4f}°", legendgroup=m, showlegend=False,
                                 line={"color": colour, "dash": "dash"}))
    fig.update_xaxes(title_text="frames in the plan (azimuths × rings × repeats + centre stage)", type="log")
    fig.update_yaxes(title_text="held-out vector error [°]", type="log")
    fig.update_layout(height=600, template="plotly_white",
                      title="CMOS plan density against accuracy: mean RMS over sensors (solid), 95 % of the max "
                            "(dashed)")
    return write_figure(fig, path)
