"""Attitude from a coarse-sun-sensor head in orbit: seed 000's LUT algorithm against the least-squares estimator.

The head is the simulated one (:mod:`drivers.sim.css_optics`, its own physics), calibrated first on the simulated
bench exactly as a lab would (each face swept through its field, :mod:`calibration.css.sweep`; every diode fitted,
:func:`calibration.css.calibrate.calibrate_css`), then flown: a tumbling cube on a circular orbit
(:mod:`drivers.sim.css_orbit`), the Sun at 1366 W/m² and the Earth below, lit (albedo 0.3) where its ground sees
the Sun and warm (288 K) everywhere. At each sunlit sample the Sun is found

* by seed 000's algorithm (listing D.5: the TPS picks the Earth faces, the 5-bit quantiser of D.6 and the rules of
  ch. 5.3.5 give azimuth and elevation; :func:`calibration.css.karel.karel_attitude`) with the thesis' own
  threshold tables, and with tables built from the bench calibration (the thesis' future work (e)), from the EPD
  and from the BPW;
* by the weighted least-squares sun-vector estimator over every lit diode (:mod:`calibration.css.estimate`), and
  by its albedo-aware variant, which is told the Earth's direction and the albedo.

Each is scored by the angle between the estimate and the true Sun, in scenes with the Earth's albedo and without
(the Earth still in view, warm, but dark — what the estimator meets on the night side of the terminator and the
thesis' algorithm meets everywhere the TPS decides). The thesis' TPS "seen temperatures" are the simulator's own
(the thesis works in measured temperature, ch. 3.4; no voltage-to-temperature curve is part of its algorithm).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.css.calibrate import calibrate_css, head_model_from_document
from calibration.css.data import CssBenchData
from calibration.css.estimate import AlbedoScene, albedo_signals, disc_quadrature, estimate_sun
from calibration.css.head import sun_vectors
from calibration.css.karel import karel_attitude
from calibration.css.quantiser import TABLES, thresholds_from_response
from calibration.css.sweep import sweep_directions
from drivers.sim.css_optics import CHANNELS, CssChannels, CssOptics, CssTruth, EarthScene
from drivers.sim.css_orbit import OrbitSamples

from .field_plots import write_figure

#: Channel indices of each detector type, in face order 1 … 6
UV = [CHANNELS.index(f"{f}_uv") for f in ("px", "py", "mx", "my", "pz", "mz")]
VIS = [CHANNELS.index(f"{f}_vis") for f in ("px", "py", "mx", "my", "pz", "mz")]
IR = [CHANNELS.index(f"{f}_ir") for f in ("px", "py", "mx", "my", "pz", "mz")]


@dataclass(frozen=True)
class OrbitReadings:
    """The head's readings at the sunlit samples of an orbit.

    Attributes
    ----------
    signals : ndarray (N, 18)
        Noisy detector signals [A or V], :data:`CHANNELS` order.
    tps_seen_c : ndarray (N, 6)
        The thermopiles' seen temperatures [°C], faces 1 … 6.
    sun_body, earth_body : ndarray (N, 3)
        True unit vectors to the Sun and the Earth's centre, body frame.
    earth_radius_deg : float
    albedo : float
        The Earth's albedo in these readings (0: a dark Earth).
    temperature_c : float
        The head's temperature.
    """
    signals: np.ndarray
    tps_seen_c: np.ndarray
    sun_body: np.ndarray
    earth_body: np.ndarray
    earth_radius_deg: float
    albedo: float
    temperature_c: float

    def earth(self, i: int) -> EarthScene:
        return EarthScene(tuple(self.earth_body[i]), self.earth_radius_deg, albedo=self.albedo,
                          sun_direction=tuple(self.sun_body[i]))


def orbit_readings(truth: CssTruth, samples: OrbitSamples, *, albedo: float = 0.3, temperature_c: float = 20.0,
                   seed: int = 0) -> OrbitReadings:
    """The head `truth`'s noisy readings at the sunlit samples of `samples` (eclipse has no Sun to find)."""
    optics = CssOptics(truth)
    rng = np.random.default_rng(seed)
    pick = np.flatnonzero(samples.sunlit)
    signals, seen = [], []
    for i in pick:
        earth = EarthScene(tuple(samples.earth_body[i]), samples.earth_radius_deg, albedo=albedo,
                           sun_direction=tuple(samples.sun_body[i]))
        signals.append(optics.reading(rng, samples.sun_body[i], 1.0, temperature_c, earth))
        seen.append(optics.tps_seen_temperature_c(earth, samples.sun_body[i]))
    return OrbitReadings(np.array(signals), np.array(seen), samples.sun_body[pick], samples.earth_body[pick],
                         samples.earth_radius_deg, albedo, temperature_c)


def angular_errors_deg(estimates, truth) -> np.ndarray:
    """Angle between estimated and true unit vectors [°]; NaN where there is no estimate."""
    e = np.asarray(estimates, float)
    t = np.asarray(truth, float)
    cos = np.sum(e * t, axis=-1) / (np.linalg.norm(e, axis=-1) * np.linalg.norm(t, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def error_figures(errors_deg, flagged=None) -> dict:
    """RMS, 50th, 95th and 99th percentile and maximum of angular errors [°] over the readings with an estimate,
    how many had none (`missing`), how many the method itself flagged as undetermined (`flagged`: a least-squares
    estimate with fewer than two non-coplanar lit faces) and the RMS over the others (`rms_determined_deg`)."""
    e = np.asarray(errors_deg, float)
    flag = np.zeros(e.shape, bool) if flagged is None else np.asarray(flagged, bool)
    ok = e[np.isfinite(e)]
    determined = e[np.isfinite(e) & ~flag]
    out = {"n": int(ok.size), "missing": int(e.size - ok.size), "flagged": int((flag & np.isfinite(e)).sum()),
           "rms_determined_deg": float(np.sqrt(np.mean(determined ** 2))) if determined.size else None}
    if ok.size == 0:
        return {**out, "rms_deg": None, "p50_deg": None, "p95_deg": None, "p99_deg": None, "max_deg": None}
    return {**out, "rms_deg": float(np.sqrt(np.mean(ok ** 2))), "p50_deg": float(np.percentile(ok, 50)),
            "p95_deg": float(np.percentile(ok, 95)), "p99_deg": float(np.percentile(ok, 99)),
            "max_deg": float(ok.max())}


# -- the head calibrated on the bench ---------------------------------------------------------------------------
def bench_calibration(truth: CssTruth, *, step_deg: float = 5.0, around: int = 8, repeats: int = 2,
                      temperature_c: float = 20.0, seed: int = 1) -> dict:
    """The head calibrated as a lab would (module docstring): each face swept through its field
    (:func:`calibration.css.sweep.sweep_directions`), `repeats` readings per direction through the head's own ADCs
    (:class:`~drivers.sim.css_optics.CssChannels`), every diode fitted; returns the calibration document."""
    optics = CssOptics(truth)
    adc = CssChannels()
    rng = np.random.default_rng(seed)
    zenith, azimuth = sweep_directions(step_deg=step_deg, around=around)
    zenith, azimuth = np.repeat(zenith, repeats), np.repeat(azimuth, repeats)
    noisy = optics.reading(rng, sun_vectors(zenith, azimuth), 1.0, temperature_c)
    signals = (adc.counts(noisy) - adc.pedestals()) * adc.units_per_count()
    data = CssBenchData(zenith, azimuth, signals, np.full(zenith.size, temperature_c), channels=CHANNELS,
                        repeat=np.tile(np.arange(repeats), zenith.size // repeats), sensor_id=truth.serial)
    return calibrate_css(data).document


def _face_vectors(normal, incidence_deg) -> np.ndarray:
    """Unit vectors at `incidence_deg` from `normal`, tilted toward a fixed perpendicular."""
    n = np.asarray(normal, float)
    helper = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    p = np.cross(n, helper)
    p /= np.linalg.norm(p)
    t = np.radians(np.asarray(incidence_deg, float))[:, None]
    return np.cos(t) * n + np.sin(t) * p


def albedo_at_normal(model, earth_radius_deg: float, albedo: float) -> dict:
    """Each detector's signal from a uniformly lit Earth disc (radiance a·E/π) centred on its normal [A or V]:
    a·S·∫_cap R dΩ/π through its calibrated response — what the albedo-aware estimator is told."""
    u, psi, w = disc_quadrature(earth_radius_deg)
    own = np.einsum("rk,r->k", model.responses_at(np.repeat(u[:, None], len(model), axis=1)), w) * psi.size
    return {c: float(albedo * s * o / np.pi) for c, s, o in zip(model.channels, model.scale, own)}


def calibrated_tables(model, *, earth_radius_deg: float, albedo: float) -> dict:
    """The thesis' quantiser tables rebuilt from the bench calibration (seed 000 ch. 7, future work (e)): the Sun
    tables from each type's calibrated response at 0 … 90° (the mean over the faces), the albedo tables from the
    calibrated response to the lit Earth disc at 0 … 90° off the normal; the TPS table stays the thesis' (no bench
    without an Earth simulator measures it)."""
    angles = np.arange(0.0, 90.0 + 1e-9, 1.0)
    level = albedo_at_normal(model, earth_radius_deg, albedo)
    tables = {"tps": TABLES["tps"].thresholds}
    for kind, prefix in (("uv", "epd"), ("vis", "bpw")):
        idx = [model.channels.index(f"{face}_{kind}") for face in ("px", "py", "mx", "my", "pz", "mz")
               if f"{face}_{kind}" in model.channels]
        sun, earth = [], []
        for i in idx:
            vectors = _face_vectors(model.normals[i], angles)
            sun.append(model.scale[i] * model.relative_responses(vectors)[:, i])
            earth.append(albedo_signals(model, AlbedoScene(vectors, earth_radius_deg, level))[:, i])
        floor = 1e-3 * float(np.mean(model.scale[idx]))
        tables[f"{prefix}_sun"] = thresholds_from_response(angles, np.mean(sun, axis=0), floor=floor)
        tables[f"{prefix}_albedo"] = thresholds_from_response(angles, np.mean(earth, axis=0))
    return tables


# -- the comparison ---------------------------------------------------------------------------------------------
def karel_vectors(readings: OrbitReadings, *, detector: str = "epd", tables=None) -> np.ndarray:
    """Seed 000's algorithm on every reading: the Sun's body vector from the EPD (``"epd"``) or BPW (``"bpw"``)."""
    out = np.empty((len(readings.signals), 3))
    for i, (m, tps) in enumerate(zip(readings.signals, readings.tps_seen_c)):
        out[i] = karel_attitude(tps, m[UV], m[VIS], tables=tables).sun_vector(detector)
    return out


def earth_lit_share(earth_vectors, earth_radius_deg: float, sun_vectors) -> np.ndarray:
    """Share of a fully lit Earth's albedo that a detector facing the Earth's centre gets when the Sun is at
    `sun_vectors`: the cosine-weighted mean over the visible disc of max(0, cos z), z the solar zenith where the
    line of sight meets the ground (a Lambertian sphere), shape (N,).

    The estimator's albedo is a uniformly lit disc (:class:`calibration.css.estimate.AlbedoScene`); this scales it to
    the Earth's phase seen from the satellite — 1 with the Sun behind the satellite, 0 with the Earth's night side
    below."""
    e = np.atleast_2d(np.asarray(earth_vectors, float))
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    s = np.atleast_2d(np.asarray(sun_vectors, float))
    s = s / np.linalg.norm(s, axis=1, keepdims=True)
    u, psi, w = disc_quadrature(earth_radius_deg)
    helper = np.where(np.abs(e[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    a = np.cross(e, helper)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(e, a)
    sin = np.sqrt(np.clip(1 - u * u, 0, None))
    cos_psi, sin_psi = np.cos(psi)[None, None, :, None], np.sin(psi)[None, None, :, None]
    side = cos_psi * a[:, None, None, :] + sin_psi * b[:, None, None, :]
    lines = u[None, :, None, None] * e[:, None, None, :] + sin[None, :, None, None] * side  # (N, rings, spokes, 3)
    radius = np.sin(np.radians(earth_radius_deg))  # the Earth's centre at unit distance
    ue = u[None, :, None]
    t = ue - np.sqrt(np.clip(radius ** 2 - (1 - ue ** 2), 0, None))
    ground = (t[..., None] * lines - e[:, None, None, :]) / radius
    lit = np.clip(np.einsum("nrsk,nk->nrs", ground, s), 0, None)
    weight = (u * w)[None, :, None]
    return (lit * weight).sum(axis=(1, 2)) / (weight.sum() * psi.size)


def least_squares_vectors(readings: OrbitReadings, model, *, albedo_aware: bool, albedo: float = 0.3):
    """The least-squares estimator on every reading, from the photodiodes (the thermopiles see the Earth's IR some
    forty times stronger than the Sun's, and their offsets are the bench room's). Albedo-aware: told the Earth's
    direction and radius and the albedo, it estimates twice — the Sun without albedo, then with the albedo of the
    Earth's phase that Sun gives (:func:`earth_lit_share`)."""
    photodiodes = [c for c in model.channels if not c.endswith("_ir")]
    sub = model.subset(photodiodes)
    cols = [CHANNELS.index(c) for c in photodiodes]
    signals = readings.signals[:, cols]
    first = estimate_sun(sub, signals, readings.temperature_c, channels=photodiodes)
    if not albedo_aware:
        return first
    share = earth_lit_share(readings.earth_body, readings.earth_radius_deg, np.nan_to_num(first.vector))
    level = albedo_at_normal(sub, readings.earth_radius_deg, albedo)
    scene = AlbedoScene(readings.earth_body, readings.earth_radius_deg, level)
    predicted = albedo_signals(sub, scene) * share[:, None]
    return estimate_sun(sub, signals, readings.temperature_c, channels=photodiodes, albedo=predicted)


def compare_attitude(truth: CssTruth, samples: OrbitSamples, *, document: dict | None = None, seed: int = 0) -> dict:
    """Every method's angular errors [°] (:func:`error_figures`) in scenes with the Earth's albedo and without, on
    the sunlit samples of `samples`; `document` is the head's bench calibration (made here when None)."""
    document = document if document is not None else bench_calibration(truth, seed=seed + 1)
    model = head_model_from_document(document)
    tables = calibrated_tables(model, earth_radius_deg=samples.earth_radius_deg, albedo=0.3)
    out: dict = {"samples": len(samples), "sunlit": int(samples.sunlit.sum()), "scenes": {}}
    for scene, albedo in (("albedo", 0.3), ("no albedo", 0.0)):
        readings = orbit_readings(truth, samples, albedo=albedo, seed=seed)
        errors = {
            "thesis LUT (EPD)": angular_errors_deg(karel_vectors(readings, detector="epd"), readings.sun_body),
            "thesis LUT (BPW)": angular_errors_deg(karel_vectors(readings, detector="bpw"), readings.sun_body),
            "thesis LUT, calibrated tables (BPW)": angular_errors_deg(
                karel_vectors(readings, detector="bpw", tables=tables), readings.sun_body),
        }
        flagged = {}
        plain = least_squares_vectors(readings, model, albedo_aware=False)
        errors["least squares"] = angular_errors_deg(plain.vector, readings.sun_body)
        flagged["least squares"] = plain.degenerate
        if albedo:
            aware = least_squares_vectors(readings, model, albedo_aware=True, albedo=albedo)
            errors["least squares, albedo-aware"] = angular_errors_deg(aware.vector, readings.sun_body)
            flagged["least squares, albedo-aware"] = aware.degenerate
        sun_earth = np.degrees(np.arccos(np.clip(np.sum(readings.sun_body * readings.earth_body, axis=1), -1, 1)))
        out["scenes"][scene] = {
            "figures": {name: error_figures(e, flagged.get(name)) for name, e in errors.items()},
            "by_sun_earth_angle": angle_table(errors, sun_earth, SUN_EARTH_BINS_DEG),
        }
        out.setdefault("errors_deg", {})[scene] = {name: [None if not np.isfinite(x) else float(x) for x in e]
                                                   for name, e in errors.items()}
        out.setdefault("sun_earth_deg", {})[scene] = sun_earth.tolist()
    return out


#: Bins of the angle between the Sun and the Earth's centre [°]: the albedo matters most where the Sun sits just
#: above the Earth's limb (65° at 660 km), where the same faces see both
SUN_EARTH_BINS_DEG = (65.0, 90.0, 120.0, 150.0, 180.0)


def angle_table(errors: dict, angle_deg, edges) -> dict:
    """RMS angular error [°] of each method in bins of `angle_deg` between `edges`, with the counts and the readings
    each method had no estimate for: {"bins": [[lo, hi], …], method: [{"n", "missing", "rms_deg"}, …]}."""
    angle = np.asarray(angle_deg, float)
    bins = list(zip(edges[:-1], edges[1:]))
    table: dict = {"bins": [[float(lo), float(hi)] for lo, hi in bins]}
    for name, e in errors.items():
        e = np.asarray(e, float)
        rows = []
        for lo, hi in bins:
            pick = (angle >= lo) & (angle < hi) if hi < edges[-1] else (angle >= lo) & (angle <= hi)
            ok = e[pick & np.isfinite(e)]
            rows.append({"n": int(ok.size), "missing": int(pick.sum() - ok.size),
                         "rms_deg": float(np.sqrt(np.mean(ok ** 2))) if ok.size else None})
        table[name] = rows
    return table


def write_attitude_plots(result: dict, path) -> Path:
    """The comparison as one HTML file (plotly): each method's cumulative error distribution per scene, and its
    errors against the Sun–Earth angle."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    scenes = list(result["errors_deg"])
    fig = make_subplots(rows=2, cols=len(scenes), subplot_titles=[f"{s}: cumulative share" for s in scenes]
                        + [f"{s}: error against the Sun–Earth angle" for s in scenes])
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"]
    for col, scene in enumerate(scenes, start=1):
        angle = result["sun_earth_deg"][scene]
        for k, (name, errors) in enumerate(result["errors_deg"][scene].items()):
            e = np.sort([x for x in errors if x is not None])
            colour = colours[k % len(colours)]
            fig.add_trace(go.Scatter(x=e, y=np.arange(1, e.size + 1) / max(len(errors), 1), mode="lines",
                                     name=name, line={"color": colour}, legendgroup=name, showlegend=col == 1),
                          row=1, col=col)
            fig.add_trace(go.Scatter(x=angle, y=errors, mode="markers", marker={"size": 3, "color": colour},
                                     name=name, legendgroup=name, showlegend=False), row=2, col=col)
        fig.update_xaxes(title_text="angular error [°]", type="log", row=1, col=col)
        fig.update_xaxes(title_text="Sun–Earth angle [°]", row=2, col=col)
        fig.update_yaxes(title_text="angular error [°]", type="log", row=2, col=col)
    fig.update_layout(height=800, title="CSS attitude: seed 000's LUT algorithm against least squares")
    return write_figure(fig, Path(path))
