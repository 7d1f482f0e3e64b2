"""The ``spline`` response law of a CSS detector (calibration.css.spline): its basis, its derivatives, its fit, and
what it achieves on the simulated head's default physics.

The head's readings come from drivers/sim/css_optics.py (its own physics, never the fit's model): the default
``fresnel`` law — cosine × the window's Fresnel transmittance × the shadow of the package's cap, a soft cut-off
over ~48–77° (visible photodiode), ~65–77° (UV), the thermopile's datasheet field curve — which neither the Kelly
nor the power law can hold, swept on the bench's plan (calibration/css/sweep.py: rings every 5° about every face's
normal out to 88°, 8 azimuths; a reduced sweep at a second temperature; Halton check directions).
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from calibration.css.calibrate import (
    apply_css_document,
    calibrate_css,
    head_model_from_document,
    validate_css_document,
)
from calibration.css.data import CssBenchData
from calibration.css.diode import DiodeParameters, HeadModel, kelly_response, signal_partials
from calibration.css.diode_fit import fit_diode
from calibration.css.head import CHANNELS, sun_vectors
from calibration.css.spline import (
    SPLINE_KNOTS_DEG,
    cosine_coefficients,
    knots_ending_at,
    spline_basis,
)
from calibration.css.sweep import halton_directions, sweep_directions
from calibration.errors import CalibrationFormatError

# --- the law ------------------------------------------------------------------------------------------------------


def test_the_spline_is_one_at_normal_incidence_zero_beyond_its_end_and_never_negative():
    knots = knots_ending_at(77.0)
    assert knots[0] == 0.0 and knots[-1] == 77.0 and all(b > a for a, b in zip(knots, knots[1:]))
    assert min(np.diff(knots)) >= 1.25  # no interval shorter than half the grid's step
    rng = np.random.default_rng(1)
    coef = np.array(cosine_coefficients(knots)) + 0.3 * rng.standard_normal(len(knots))  # a wild one
    p = DiodeParameters("px_vis", "spline", spline=tuple(coef), spline_knots_deg=knots)
    theta = np.linspace(0.0, 180.0, 3601)
    r = p.relative_response(np.cos(np.radians(theta)))
    assert r[0] == pytest.approx(1.0, abs=1e-14)
    assert np.all(r >= 0.0) and np.all(r[theta >= 77.0] == 0.0)
    # the default coefficients are the spline nearest the cosine
    plain = DiodeParameters("px_vis", "spline")
    assert plain.spline_knots_deg == SPLINE_KNOTS_DEG and len(plain.spline) == len(SPLINE_KNOTS_DEG)
    g = np.cos(np.radians(theta[theta < 89.0]))
    assert np.max(np.abs(plain.relative_response(g) - g)) < 2e-3
    # the knots thin out where the readings' incidences do not support them: rings every 15°, 6 directions each
    rings = np.repeat(np.arange(0.0, 88.0, 15.0), 6)
    sparse = knots_ending_at(80.0, support=rings)
    assert len(sparse) < len(knots_ending_at(80.0)) and sparse[-1] == 80.0
    counts = np.histogram(rings, bins=np.r_[sparse[:-1], 80.0 + 1e-9])[0]
    assert np.all(counts >= 4)
    with pytest.raises(ValueError, match=f"{len(knots)} knots has {len(knots)} coefficients, got 3"):
        DiodeParameters("px_vis", "spline", spline=(1.0, 0.5, 0.2), spline_knots_deg=knots)
    with pytest.raises(ValueError, match="rise strictly from 0 to at most 90°"):
        DiodeParameters("px_vis", "spline", spline_knots_deg=(0.0, 50.0, 95.0))
    with pytest.raises(ValueError, match="belong to the spline law"):
        DiodeParameters("px_vis", "kelly", spline=(1.0,))


def test_partial_derivatives_of_the_spline_law_agree_with_finite_differences():
    rng = np.random.default_rng(3)
    s = rng.standard_normal((400, 3))
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    t = rng.uniform(10, 40, 400)
    lit = rng.random(400) > 0.1
    knots = knots_ending_at(78.0)
    coef = np.array(cosine_coefficients(knots)) * (1 + 0.05 * rng.standard_normal(len(knots)))
    p = DiodeParameters("py_vis", "spline", scale=2e-3, bias=1e-8, tilt_u_deg=1.2, tilt_v_deg=-0.7,
                        temp_coeff_per_c=-5e-4, bias_temp_coeff_per_c=2e-10, spline=tuple(coef),
                        spline_knots_deg=knots)
    m, partials = signal_partials(p, s, t, lit)
    assert set(p.spline_names) <= set(partials) and np.all(partials["shape"] == 0.0)
    for name, step in [("scale", 1e-7), ("bias", 1e-10), ("tilt_u_deg", 1e-5), ("tilt_v_deg", 1e-5),
                       ("spline_1", 1e-6), ("spline_7", 1e-6), (p.spline_names[-1], 1e-6),
                       ("temp_coeff_per_c", 1e-7), ("bias_temp_coeff_per_c", 1e-12)]:
        hi = signal_partials(p.with_values(**{name: p.get(name) + step}), s, t, lit)[0]
        lo = signal_partials(p.with_values(**{name: p.get(name) - step}), s, t, lit)[0]
        numeric = (hi - lo) / (2 * step)
        scale = np.max(np.abs(numeric)) + 1e-30
        assert np.max(np.abs(numeric - partials[name])) < 1e-5 * scale, name
    # ∂m/∂s of a head mixing the laws (the estimator's Gauss–Newton), away from the Kelly detector's ramp corners
    params = [p, DiodeParameters("px_uv", "kelly", scale=1.0, shape=0.2, fov_half_deg=75.0),
              DiodeParameters("pz_ir", "spline", scale=3.0, tilt_u_deg=2.0),
              DiodeParameters("mz_uv", "power", scale=0.5, shape=1.3)]
    head = HeadModel.from_parameters(params)
    values, grad = head.signals_and_gradient(s, 30.0)
    assert values == pytest.approx(np.stack([q.signal(s, 30.0) for q in params], axis=1), rel=1e-12, abs=1e-18)
    theta = np.degrees(np.arccos(np.clip(s @ head.normals.T, -1, 1)))
    smooth = (np.abs(np.abs(theta[:, 1] - 75.0) - 1.0) > 0.01)[:, None] & (np.abs(theta - 90.0) > 0.01)
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-7
        numeric = (head.signals(s + d, 30.0) - head.signals(s - d, 30.0)) / 2e-7
        assert np.max(np.abs(numeric - grad[..., k])[smooth]) < 1e-5
    # a head of spline detectors on different knots evaluates each on its own
    other = p.with_values(spline_knots_deg=SPLINE_KNOTS_DEG, spline=cosine_coefficients())
    pair = HeadModel.from_parameters([p, other.with_values(channel="mx_vis")])
    assert pair.signals(s)[:, 0] == pytest.approx(p.signal(s), rel=1e-14, abs=1e-20)
    assert pair.subset(["mx_vis"]).signals(s)[:, 0] == pytest.approx(pair.signals(s)[:, 1], rel=1e-14, abs=1e-20)


def test_a_smooth_detector_is_fitted_to_its_noise_with_honest_uncertainties():
    """A Kelly-law detector without a cut-off (smooth down to grazing incidence), its readings written from the
    law's definition at 800 random directions × 2 repeats at 15–35 °C: the spline fits it to its noise and every
    parameter lies within 4σ of the truth. Achieved: χ²/dof 0.93, all within 0.6σ, the response within 2.4e-5 of
    the law over 0–88°."""
    from test_diode_fit import independent_readings, true_tilts

    rng = np.random.default_rng(11)
    sun, y, t, dark = independent_readings(rng, fov=None, directions=800)
    fit = fit_diode("px_uv", sun, y, t, dark=dark, response="spline")
    assert fit.valid and fit.rejected == () and 0.85 < fit.chi2_dof < 1.15
    tu, tv = true_tilts("px", 88.0, 2.0)
    truth = {"scale": 5e-6, "bias": 2e-10, "tilt_u_deg": tu, "tilt_v_deg": tv, "temp_coeff_per_c": 1e-3,
             "bias_temp_coeff_per_c": 3e-12}
    for name, value in truth.items():
        assert abs(fit.values[name] - value) < 4 * fit.sd[name], (name, fit.values[name], value, fit.sd[name])
    theta = np.arange(0.0, 88.5, 0.5)
    g = np.cos(np.radians(theta))
    assert np.max(np.abs(fit.parameters.relative_response(g) - kelly_response(g, 0.15))) < 2e-4
    assert "fov_half_deg" not in fit.free and fit.values["fov_half_deg"] is None
    assert any("spline law's" in s and "knots every 10° from 0 to 40°" in s for s in fit.statements)
    # a glint (5 % more light on one reading; its repeat is clean) is still told from the law
    lit = np.flatnonzero(~dark & (np.nan_to_num(sun) @ fit.parameters.normal > 0.6))
    y2 = y.copy()
    y2[lit[3]] *= 1.05
    glint = fit_diode("px_uv", sun, y2, t, dark=dark, response="spline", row_id=np.arange(1, y.size + 1))
    assert [r.row_id for r in glint.rejected] == [lit[3] + 1] and "glint" in glint.rejected[0].reason


# --- the simulated head's default (fresnel) physics ----------------------------------------------------------------


def sweep_run(law: str = "fresnel", seed: int = 11, *, temperatures=(25.0, 40.0), repeats: int = 2, dark: int = 8,
              checks: int = 24):
    """A bench run of a head from css_optics on the bench's plan: at the first temperature every face's rings
    (calibration.css.sweep: 0–88° every 5°, 8 azimuths) and `checks` Halton check directions, at the others the
    reduced sweep (rings every 30° × 4 azimuths), each ring direction `repeats` times, `dark` shutter-closed
    readings per temperature, the plate's temperature held to ±0.05 °C, the simulator's own noise."""
    from drivers.sim.css_optics import CssOptics, css_truth

    truth = css_truth(seed=seed, response=law)
    optics = CssOptics(truth)
    rng = np.random.default_rng(seed)
    zenith, azimuth, temp, is_dark, is_check, repeat = [], [], [], [], [], []

    def add(z, a, t, d, c, r):
        for lst, v in ((zenith, z), (azimuth, a), (temp, np.full(len(z), t)), (is_dark, np.full(len(z), d)),
                       (is_check, np.full(len(z), c)), (repeat, np.full(len(z), r))):
            lst.append(np.asarray(v))

    for k, t in enumerate(temperatures):
        add(np.full(dark, np.nan), np.full(dark, np.nan), t, True, False, 0)
        z, a = sweep_directions(88.0, 5.0, 8) if k == 0 else sweep_directions(88.0, 30.0, 4, edge=False)
        for r in range(repeats):
            add(z, a, t, False, False, r)
        if k == 0 and checks:
            add(*halton_directions(checks), t, False, True, 0)
    z, a, t = (np.concatenate(v) for v in (zenith, azimuth, temp))
    t = t + 0.05 * rng.standard_normal(t.size)
    is_dark = np.concatenate(is_dark).astype(bool)
    s = sun_vectors(np.nan_to_num(z), np.nan_to_num(a))
    clean = optics.signals(s, np.where(is_dark, 0.0, 1.0)[:, None], t)
    noise = np.stack([optics.noise_sd(clean[i], t[i]) for i in range(t.size)])
    signals = clean + noise * rng.standard_normal(clean.shape)
    data = CssBenchData(z, a, signals, t, repeat=np.concatenate(repeat), dark=is_dark,
                        check=np.concatenate(is_check).astype(bool), sensor_id=truth.serial)
    return truth, optics, data


@pytest.fixture(scope="module")
def fresnel_run():
    return sweep_run()


@pytest.fixture(scope="module")
def spline_fit(fresnel_run):
    return calibrate_css(fresnel_run[2], response="spline")


@pytest.fixture(scope="module")
def kelly_fit(fresnel_run):
    return calibrate_css(fresnel_run[2], response="kelly")


def test_the_spline_follows_the_fresnel_heads_response_and_recovers_its_normals(fresnel_run, spline_fit):
    """Stated tolerances: over 0–80° of incidence the fitted relative response lies within 0.004 of the simulator's
    own (css_optics.response: cosine × Fresnel window × cap shadow; the thermopile's datasheet curve) for the
    photodiodes, within 0.015 for the thermopiles (whose noise is 0.35 % of their scale); every normal within 3× its
    stated 1σ or 0.01°; no reading rejected (the head has no glint). The spline's end (the field's edge) lies
    between the cap's shadow's end on the true normal and 2° beyond it for the photodiodes.

    Achieved (seed 11, 1432 readings): response within 0.0011–0.0014 (UV), 0.0005 (visible), 0.003–0.007
    (thermopiles); normals 0.001–0.003° off (photodiodes, 1σ 0.0005–0.0012°: at most 3.1× it, the spline's own misfit
    at the cap shadow's edges moves them that much) and 0.006–0.030° (thermopiles, at most 1.8σ); ends 76.5–77.5°
    (UV, the shadow ends at 76.6°), 77–78° (visible, 77.1°), 79–85° (thermopiles, whose datasheet curve has
    faded to 0.5 % by 80°)."""
    from drivers.sim.css_optics import CAPS, response

    truth, _, _ = fresnel_run
    out = spline_fit
    assert out.response == "spline" and out.faulty == {} and out.rejected == []
    theta = np.arange(0.0, 80.01, 0.25)
    g = np.cos(np.radians(theta))
    for c, fit in out.fits.items():
        d = truth.diode(c)
        kind = c.split("_")[1]
        error = np.max(np.abs(fit.parameters.relative_response(g) - response(d, g)))
        assert error < (0.015 if kind == "ir" else 0.004), (c, error)
        miss = np.degrees(np.arccos(np.clip(fit.parameters.normal @ d.normal, -1, 1)))
        assert miss < max(3 * fit.normal_sd_deg, 0.01), (c, miss, fit.normal_sd_deg)
        if kind != "ir":
            a, r, h = CAPS[kind]
            shadow_end = np.degrees(np.arctan((a + r) / h))
            assert shadow_end - 0.5 <= fit.parameters.spline_knots_deg[-1] <= shadow_end + 2.0, c
        assert "spline_1" in fit.free and "fov_half_deg" not in fit.free


def test_the_spline_holds_the_sun_direction_far_better_than_the_kelly_law(spline_fit, kelly_fit):
    """Held out (5 interleaved folds of the sweep's directions, each refitted without them), the Sun's direction
    from the spline law's calibration is far better than from the Kelly law's on the same readings: asserted below
    0.6° RMS against above 1.5°, and at least 5× better (check directions: below 0.3° against above 0.8°).

    Achieved (seed 11): held out 0.179° RMS (p95 0.34°, over 1067 readings) with the spline against 3.16° (p95 4.8°,
    over 903) with the Kelly law; at the check directions 0.115° against 1.38°. (The spline's RMS is set by a few
    readings that light one face well and a second only at the edge of its field — near-degenerate; at the fitted
    directions its median error is 0.009°.) Fit time on this machine (2 cores, shared): 7–10 s for the spline law,
    19–33 s for the Kelly law (whose misfit sends many readings to the estimator's restarts)."""
    from bench.css_datafile import rank_css_fits

    spline, kelly = spline_fit.sun_heldout, kelly_fit.sun_heldout
    assert spline.n_points > 500 and kelly.n_points > 500
    assert spline.rms_deg < 0.6 and kelly.rms_deg > 1.5 and kelly.rms_deg > 5 * spline.rms_deg
    assert spline_fit.sun_check.rms_deg < 0.3 < 0.8 < kelly_fit.sun_check.rms_deg
    assert rank_css_fits([kelly_fit, spline_fit])[0] is spline_fit


def test_the_estimators_stated_uncertainty_stays_honest_on_the_spline_head(spline_fit):
    """The held-out angle errors over the estimator's own 1σ (which counts the reading noise and each detector's
    model error): RMS within 0.8–1.25. Achieved: 1.07 (the model error the spline law adds to its photodiodes'
    noise, 1–2.5 × 10⁻⁴ of their scale, carries its misfit at the cap shadow's edges)."""
    held = spline_fit.sun_heldout
    assert 0.8 < held.normalised_rms < 1.25
    assert spline_fit.document["uncertainty_scale"] == pytest.approx(max(1.0, held.normalised_rms))
    for c, fit in spline_fit.fits.items():
        assert fit.parameters.model_sd < 1e-3 * fit.parameters.scale, c


def test_the_spline_document_round_trips_and_applies_alone(fresnel_run, spline_fit):
    _, optics, _ = fresnel_run
    doc = spline_fit.document
    assert doc["response"] == "spline" and doc["version"] == 1
    entry = doc["diodes"]["py_vis"]
    knots = entry["spline_knots_deg"]
    names = [f"spline_{k}" for k in range(1, len(knots) + 1)]
    assert set(entry["parameters"]) == {"scale", "bias", "tilt_u_deg", "tilt_v_deg", "fov_half_deg",
                                        "temp_coeff_per_c", "bias_temp_coeff_per_c", *names}
    assert entry["parameters"]["fov_half_deg"] == {"value": None, "sd": None, "fitted": False}
    assert all(entry["parameters"][n]["fitted"] and entry["parameters"][n]["sd"] > 0 for n in names)
    assert names[0] in entry["covariance"]["names"] and "B-splines" in doc["model"]["response"]
    restored = json.loads(json.dumps(doc))
    validate_css_document(restored)
    head = head_model_from_document(restored)
    rng = np.random.default_rng(8)
    v = rng.standard_normal((300, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    assert head.signals(v, 31.0) == pytest.approx(spline_fit.head.signals(v, 31.0), rel=1e-12, abs=1e-20)
    clean = optics.signals(v, 1.0, 31.0)
    y = clean + optics.noise_sd(clean, 31.0) * rng.standard_normal(clean.shape)
    est = apply_css_document(restored, y, CHANNELS, 31.0)
    ok = ~est.degenerate
    err = np.degrees(np.arccos(np.clip(np.sum(est.vector[ok] * v[ok], axis=1), -1, 1)))
    assert ok.mean() > 0.75 and np.median(err) < 0.05
    # the document's checks name a spline's problems
    for change, message in [
            (lambda d: d["diodes"]["px_uv"].pop("spline_knots_deg"), "px_uv: the spline law needs `spline_knots_deg`"),
            (lambda d: d["diodes"]["px_uv"].update(spline_knots_deg=[0, 50, 40, 80]), "rise strictly"),
            (lambda d: d["diodes"]["px_uv"]["parameters"].pop("spline_3"), "parameter `spline_3` missing"),
            (lambda d: d["diodes"]["px_uv"]["spline_knots_deg"].append(89.5), "parameter `spline_.*` missing")]:
        broken = copy.deepcopy(doc)
        change(broken)
        with pytest.raises(CalibrationFormatError, match=message):
            validate_css_document(broken)


def test_the_c_header_evaluates_the_same_spline(tmp_path, spline_fit):
    """calibration.css.export.c_header of the fresnel head's spline calibration, with a Kelly and a power detector
    beside it: compiled, its sunbench_css_signal() gives the Python model's signal to 1e-12 (relative) at 2000
    random directions — the spline's piecewise cubics, their clamp at zero and their end included."""
    import subprocess

    from ccompiler import c_compiler

    from calibration.css.export import c_header

    diodes = [spline_fit.fits[c].parameters for c in CHANNELS if c not in ("mz_uv", "mz_vis")]
    diodes += [DiodeParameters("mz_uv", "kelly", scale=6e-6, shape=0.2, fov_half_deg=78.0),
               DiodeParameters("mz_vis", "power", scale=1e-3, shape=1.3, bias=2e-9)]
    header = tmp_path / "css.h"
    header.write_text(c_header(diodes, sensor_id="CSS-SPLINE"))
    program = tmp_path / "signals.c"
    program.write_text(f'#include <stdio.h>\n#include "{header}"\n'
                       "int main(void) { int k; double s[3], t;\n"
                       '  while (scanf("%d %lf %lf %lf %lf", &k, &s[0], &s[1], &s[2], &t) == 5)\n'
                       '    printf("%.17g\\n", sunbench_css_signal(k, s, t));\n  return 0; }\n')
    exe = tmp_path / "signals"
    done = subprocess.run([c_compiler(), "-std=c99", "-Wall", "-Wextra", "-Werror", str(program), "-o", str(exe),
                           "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rng = np.random.default_rng(4)
    v = rng.standard_normal((2000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    t = rng.uniform(10, 40, 2000)
    lines, want = [], []
    for d in diodes:
        k = CHANNELS.index(d.channel)
        lines += [f"{k} {x!r} {y!r} {z!r} {tt!r}" for (x, y, z), tt in zip(v.tolist(), t.tolist())]
        want.append(d.signal(v, t))
    done = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True, text=True)
    got = np.array(done.stdout.split(), float).reshape(len(want), -1)
    want = np.array(want)
    assert np.max(np.abs(got - want) / np.maximum(np.abs(want), 1e-15)) < 1e-12
    assert spline_basis(diodes[0].spline_knots_deg).n_intervals == len(diodes[0].spline_knots_deg) - 1
