"""One CSS detector's model (calibration.css.diode) and its fit (calibration.css.diode_fit).

Data come from generators that do not call the fit's forward model: :func:`independent_readings` below (the law
written again from its definition: angles, not the model's code path), and, for the coverage test, the head's
simulated physics drivers/sim/css_optics.py (DESIGN.md: a simulator is its own physics).
"""

from __future__ import annotations

import numpy as np
import pytest

from calibration.css.diode import (
    FOV_EDGE_WIDTH_DEG,
    DiodeParameters,
    HeadModel,
    fov_edge,
    kelly_response,
    normal_angles,
    power_response,
    signal_partials,
    tilted_normal,
    tilts_from_normal,
)
from calibration.css.diode_fit import direction_groups, fit_diode, fit_noise_model, model_error

# --- an independent generator ---------------------------------------------------------------------------------------


def unit(zenith_deg, azimuth_deg):
    th, ph = np.radians(zenith_deg), np.radians(azimuth_deg)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)


def independent_readings(rng, *, normal=(88.0, 2.0), scale=5e-6, bias=2e-10, law="kelly", shape=0.15, fov=78.0,
                         c_t=1e-3, b_t=3e-12, sigma0=2e-10, shot=3e-15, directions=500, repeats=2, dark=20,
                         t_range=(15.0, 35.0), grid=None):
    """Readings of one detector by the law's definition: the incidence θ between the Sun and the normal (given as
    body zenith/azimuth), the Kelly or power law of cos θ, the field edge a straight line from 1 at θc − w/2 to 0 at
    θc + w/2 (np.interp), gain and offset linear in temperature, and Gaussian noise of variance σ0² + q·|m|."""
    if grid is None:
        v = rng.standard_normal((directions, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
    else:
        v = grid
    n_hat = unit(*normal)
    sun = np.concatenate([v] * repeats + [np.full((dark, 3), np.nan)])
    is_dark = np.r_[np.zeros(v.shape[0] * repeats, bool), np.ones(dark, bool)]
    temp = rng.uniform(*t_range, sun.shape[0])
    theta = np.degrees(np.arccos(np.clip(np.nan_to_num(sun) @ n_hat, -1.0, 1.0)))
    c = np.cos(np.radians(theta))
    if law == "kelly":
        law_value = c * (1.0 - np.exp(-c * c / shape)) / (1.0 - np.exp(-1.0 / shape))
    else:
        law_value = np.abs(c) ** shape
    law_value = np.where(theta < 90.0, law_value, 0.0)
    edge = np.ones_like(theta) if fov is None else np.interp(theta, [fov - FOV_EDGE_WIDTH_DEG / 2,
                                                                      fov + FOV_EDGE_WIDTH_DEG / 2], [1.0, 0.0])
    light = np.where(is_dark, 0.0, scale * (1 + c_t * (temp - 25.0)) * law_value * edge)
    clean = light + bias + b_t * (temp - 25.0)
    noisy = clean + np.sqrt(sigma0**2 + shot * np.abs(clean)) * rng.standard_normal(clean.size)
    return sun, noisy, temp, is_dark


def true_tilts(face, zenith_deg, azimuth_deg):
    return tuple(float(t) for t in tilts_from_normal(face, unit(zenith_deg, azimuth_deg)))


# --- the model --------------------------------------------------------------------------------------------------------


def test_response_laws_are_one_at_normal_incidence_and_zero_behind():
    g = np.array([1.0, 0.5, 0.0, -0.3])
    k = kelly_response(g, 0.2)
    assert k[0] == pytest.approx(1.0) and k[2] == 0.0 and k[3] == 0.0
    assert k[1] == pytest.approx(0.5 * (1 - np.exp(-0.25 / 0.2)) / (1 - np.exp(-5.0)))
    assert kelly_response(0.5, 1e-4) == pytest.approx(0.5)  # κ → 0: the plain cosine
    assert power_response(g, 2.0).tolist() == pytest.approx([1.0, 0.25, 0.0, 0.0])
    assert fov_edge([70.0, 80.0, 81.0, 85.0], 80.0).tolist() == pytest.approx([1.0, 0.5, 0.0, 0.0])
    assert fov_edge([89.0], None).tolist() == [1.0]


@pytest.mark.parametrize("face", ["px", "py", "mx", "my", "pz", "mz"])
def test_tilts_round_trip_on_every_face_without_a_singularity(face):
    n = tilted_normal(face, 2.5, -1.5)
    assert np.linalg.norm(n) == pytest.approx(1.0)
    assert tilts_from_normal(face, n) == pytest.approx((2.5, -1.5))
    zen, az = normal_angles(face, 0.0, 0.0)
    assert np.all(np.isfinite([zen, az]))
    # a small tilt moves the normal by about that angle, on the poles as on the sides
    assert np.degrees(np.arccos(n @ tilted_normal(face))) == pytest.approx(np.hypot(2.5, 1.5), rel=2e-3)


@pytest.mark.parametrize("law", ["kelly", "power"])
def test_partial_derivatives_agree_with_finite_differences(law):
    rng = np.random.default_rng(3)
    s = rng.standard_normal((400, 3))
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    t = rng.uniform(10, 40, 400)
    lit = rng.random(400) > 0.1
    p = DiodeParameters("py_vis", law, scale=2e-3, bias=1e-8, tilt_u_deg=1.2, tilt_v_deg=-0.7,
                        shape=0.2 if law == "kelly" else 1.3, fov_half_deg=72.0, temp_coeff_per_c=-5e-4,
                        bias_temp_coeff_per_c=2e-10)
    m, partials = signal_partials(p, s, t, lit)
    for name, step in [("scale", 1e-7), ("bias", 1e-10), ("tilt_u_deg", 1e-5), ("tilt_v_deg", 1e-5),
                       ("shape", 1e-6), ("fov_half_deg", 1e-5), ("temp_coeff_per_c", 1e-7),
                       ("bias_temp_coeff_per_c", 1e-12)]:
        hi = signal_partials(p.with_values(**{name: getattr(p, name) + step}), s, t, lit)[0]
        lo = signal_partials(p.with_values(**{name: getattr(p, name) - step}), s, t, lit)[0]
        numeric = (hi - lo) / (2 * step)
        # away from the ramp's two corners, where the derivative jumps
        theta = np.degrees(np.arccos(np.clip(s @ p.normal, -1, 1)))
        smooth = np.abs(np.abs(theta - 72.0) - FOV_EDGE_WIDTH_DEG / 2) > 0.01
        scale = np.max(np.abs(numeric)) + 1e-30
        assert np.max(np.abs(numeric - partials[name])[smooth]) < 1e-5 * scale, name


def test_head_model_gradient_with_respect_to_the_sun_vector():
    rng = np.random.default_rng(4)
    params = [DiodeParameters(c, "kelly", scale=1.0 + i, tilt_u_deg=0.3 * i, shape=0.1 + 0.05 * i,
                              fov_half_deg=75.0) for i, c in enumerate(["px_uv", "py_ir", "pz_vis", "mz_uv"])]
    head = HeadModel.from_parameters(params)
    s = rng.standard_normal((50, 3))
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    m, grad = head.signals_and_gradient(s, 30.0)
    assert m == pytest.approx(np.stack([p.signal(s, 30.0) for p in params], axis=1))
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-7
        numeric = (head.signals(s + d, 30.0) - head.signals(s - d, 30.0)) / 2e-7
        theta = np.degrees(np.arccos(np.clip(s @ head.normals.T, -1, 1)))
        smooth = np.abs(np.abs(theta - 75.0) - 1.0) > 0.01
        assert np.max(np.abs(numeric - grad[..., k])[smooth]) < 1e-5


# --- the fit on the independent generator ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def kelly_fit():
    rng = np.random.default_rng(11)
    sun, y, t, dark = independent_readings(rng)
    return fit_diode("px_uv", sun, y, t, dark=dark), (sun, y, t, dark)


def test_fit_recovers_every_parameter_of_an_in_class_detector(kelly_fit):
    fit, _ = kelly_fit
    assert fit.valid and fit.fault is None
    tu, tv = true_tilts("px", 88.0, 2.0)
    truth = {"scale": 5e-6, "bias": 2e-10, "tilt_u_deg": tu, "tilt_v_deg": tv, "kappa": 0.15, "fov_half_deg": 78.0,
             "temp_coeff_per_c": 1e-3, "bias_temp_coeff_per_c": 3e-12}
    assert set(fit.free) == set(truth)
    for name, value in truth.items():
        assert abs(fit.values[name] - value) < 4 * fit.sd[name], (name, fit.values[name], value, fit.sd[name])
    assert 0.85 < fit.chi2_dof < 1.15
    assert fit.noise_source == "repeats"
    assert fit.normal_zenith_deg == pytest.approx(88.0, abs=0.05)
    assert fit.normal_azimuth_deg == pytest.approx(2.0, abs=0.05)
    # the noise model σ² = σ0² + q|m| (+ (r m)²) from the repeats: within 10 % where most readings are, 30 % at the
    # top, where few directions are (q and r are nearly degenerate over one decade of signal)
    p = fit.parameters
    for level, tolerance in ((2e-10, 0.1), (1e-6, 0.1), (3e-6, 0.15), (5e-6, 0.3)):
        true_sd = np.sqrt((2e-10) ** 2 + 3e-15 * level)
        assert p.noise_sd(level) == pytest.approx(true_sd, rel=tolerance)
    assert any("c_T and b_T fitted" in s for s in fit.statements)
    corr = fit.correlation
    assert np.allclose(np.diag(corr), 1.0) and np.allclose(corr, corr.T)
    assert fit.to_dict()["parameters"]["kappa"]["fitted"]


def test_fit_predict_reproduces_the_model(kelly_fit):
    fit, (sun, y, t, dark) = kelly_fit
    pred = fit.predict(sun, t, dark=dark)
    assert np.nanstd((y - pred)[fit.used]) == pytest.approx(fit.rms, rel=1e-6)


def test_power_law_detector():
    rng = np.random.default_rng(12)
    sun, y, t, dark = independent_readings(rng, law="power", shape=1.4, normal=(3.0, 40.0), fov=70.0)
    fit = fit_diode("pz_vis", sun, y, t, dark=dark, response="power")
    assert fit.valid
    assert abs(fit.values["power"] - 1.4) < 4 * fit.sd["power"]
    assert abs(fit.values["fov_half_deg"] - 70.0) < 4 * fit.sd["fov_half_deg"]
    tu, tv = true_tilts("pz", 3.0, 40.0)
    assert abs(fit.values["tilt_u_deg"] - tu) < 4 * fit.sd["tilt_u_deg"]


def test_temperature_terms_are_held_when_the_readings_do_not_span_three_degrees():
    rng = np.random.default_rng(13)
    sun, y, t, dark = independent_readings(rng, t_range=(24.0, 25.5), c_t=0.0, b_t=0.0)
    fit = fit_diode("px_uv", sun, y, t, dark=dark)
    assert not fit.temperature_fitted
    assert "temp_coeff_per_c" not in fit.free and fit.values["temp_coeff_per_c"] == 0.0
    assert any("not fitted" in s and "under 3 °C" in s for s in fit.statements)


def test_the_fov_cut_off_is_not_fitted_without_readings_beyond_70_degrees():
    rng = np.random.default_rng(14)
    zen, az = np.meshgrid(np.arange(0, 66, 5.0), np.arange(0, 360, 30.0), indexing="ij")
    grid = unit(zen.ravel(), az.ravel())  # around +Z: pz sees at most ~66°
    sun, y, t, dark = independent_readings(rng, normal=(1.0, 0.0), grid=grid, fov=None)
    fit = fit_diode("pz_uv", sun, y, t, dark=dark)
    assert fit.valid and not fit.fov_fitted and fit.values["fov_half_deg"] is None
    assert any("FOV cut-off is not constrained: no reading beyond 70° incidence" in w for w in fit.warnings)


def test_no_repeats_noise_from_residuals_says_so():
    rng = np.random.default_rng(15)
    sun, y, t, dark = independent_readings(rng, repeats=1, dark=0, directions=700)
    fit = fit_diode("px_uv", sun, y, t, dark=dark)
    assert fit.noise_source == "residuals"
    assert any("no repeated directions" in w for w in fit.warnings)


def test_a_glint_is_rejected_and_named():
    rng = np.random.default_rng(16)
    sun, y, t, dark = independent_readings(rng)
    lit = np.flatnonzero(~dark & (np.nan_to_num(sun) @ unit(88.0, 2.0) > 0.6))
    row = int(lit[3])
    y = y.copy()
    y[row] *= 1.05  # a glint: 5 % more light on one reading (thousands of sigmas)
    fit = fit_diode("px_uv", sun, y, t, dark=dark, row_id=np.arange(1, y.size + 1) + 100)
    assert [r.row_id for r in fit.rejected] == [row + 101]
    assert "glint" in fit.rejected[0].describe() and fit.rejected[0].channel == "px_uv"
    assert not fit.used[row]
    tu, _ = true_tilts("px", 88.0, 2.0)
    assert abs(fit.values["tilt_u_deg"] - tu) < 4 * fit.sd["tilt_u_deg"]


# --- faults -----------------------------------------------------------------------------------------------------------


def test_stuck_dead_inverted_and_saturated_channels_are_told_in_words():
    rng = np.random.default_rng(17)
    sun, y, t, dark = independent_readings(rng)
    stuck = fit_diode("px_vis", sun, np.full(y.size, 1.25e-6), t, dark=dark)
    assert stuck.fault == "stuck" and not stuck.valid and stuck.parameters is None
    assert "px_vis: every reading is 1.25e-06 A — a stuck channel" in stuck.warnings[0]
    dead = fit_diode("px_vis", sun, 2e-10 + 2e-10 * rng.standard_normal(y.size), t, dark=dark)
    assert dead.fault == "dead"
    assert "px_vis: the readings do not change with the Sun's direction — a stuck or dead diode" in dead.warnings[0]
    inverted = fit_diode("px_vis", sun, 1e-5 - y, t, dark=dark)
    assert inverted.fault == "inverted" and "inverted or swapped" in inverted.warnings[0]
    full = 3e-6
    clipped = np.minimum(y, full)
    sat = fit_diode("px_uv", sun, clipped, t, dark=dark, full_scale=full)
    assert sat.fault == "saturated" and "at the front end's full scale" in sat.warnings[0]
    assert "saturated" in sat.warnings[0]
    # clipped at a level found from the data alone (no full scale given; the readings at the top share one value
    # over more than 10° of incidence), near normal incidence only: those are left out, the rest is fitted
    few = np.minimum(y, 0.95 * y.max())
    partly = fit_diode("px_uv", sun, few, t, dark=dark)
    assert partly.valid and len(partly.rejected) >= 3
    assert all("saturated" in r.reason for r in partly.rejected)
    assert any("left out of the fit" in w for w in partly.warnings)


def test_a_detector_never_lit_is_not_calibrated():
    rng = np.random.default_rng(18)
    sun, y, t, dark = independent_readings(rng, normal=(90.0, 180.0))
    grazing = np.nan_to_num(sun) @ np.array([-1.0, 0.0, 0.0]) < 0.5  # the Sun never within 60° of mx's normal
    keep = dark | grazing
    fit = fit_diode("mx_uv", sun[keep], y[keep], t[keep], dark=dark[keep])
    assert fit.fault == "unlit" and "lit within 60° of its normal at 0 direction(s) only" in fit.warnings[0]
    assert "not calibrated" in fit.warnings[0]


# --- helpers ----------------------------------------------------------------------------------------------------------


def test_noise_model_from_group_variances():
    rng = np.random.default_rng(19)
    level = np.r_[np.full(200, 1e-10), rng.uniform(0, 6e-6, 400)]
    var = 1e-21 + 2e-15 * level + (3e-4 * level) ** 2
    s2 = var * rng.chisquare(1, level.size)
    sigma0, q, r = fit_noise_model(s2, level, np.ones(level.size))
    assert sigma0 == pytest.approx(np.sqrt(1e-21), rel=0.15)
    assert r == pytest.approx(3e-4, rel=0.25)


def test_model_error_makes_chi2_per_dof_one():
    rng = np.random.default_rng(20)
    noise = np.full(1000, 1.0)
    resid = rng.standard_normal(1000) * np.sqrt(1.0 + 4.0)
    tau = model_error(resid, noise, 1000)
    assert np.sum(resid**2 / (1.0 + tau**2)) == pytest.approx(1000, rel=1e-4)
    assert tau == pytest.approx(2.0, rel=0.1)
    assert model_error(rng.standard_normal(1000), noise, 1000) == 0.0


def test_direction_groups_keep_repeats_together_and_checks_apart():
    v = unit(np.array([10.0, 10.0, 10.001, 50.0, np.nan]), np.array([0.0, 0.0, 0.0, 20.0, np.nan]))
    groups = direction_groups(v, dark=np.array([0, 0, 0, 0, 1], bool), check=np.array([0, 1, 0, 0, 0], bool))
    assert groups[0] == groups[2] != groups[1]
    assert len(set(groups.tolist())) == 4


# --- coverage against the head's own simulated physics ---------------------------------------------------------------


#: Noise draws of the coverage test (each 3 fits; 200 gave the same shares within a point, at twice the time)
DRAWS = 120


def test_coverage_of_the_stated_uncertainties_with_a_model_class_truth():
    """DRAWS (120) noise draws of one bench run (400 random directions × 2 repeats at 15–35 °C, 20 dark readings) of
    a head from drivers/sim/css_optics with the "kelly" law (Basilisk's law with a 2° linear field edge: the model's
    class), three detectors fitted per draw (px_uv, py_vis, pz_ir: one of each type). For every fitted parameter,
    pooled over the three, the share of draws within 1σ and 2σ of the truth must be 60–76 % and ≥ 90 %.

    Achieved (draws seeded 1000…1119; 360 fits per parameter, θ_c 350: the thermopile's cut-off at 85° is left
    unfitted in 10 draws where it ran past 90°, its edge 1.5σ deep): within 1σ / 2σ — scale 70.0/94.2 %, bias
    68.3/97.8 %, tilt_u 65.3/94.4 %, tilt_v 67.8/94.2 %, κ 65.6/95.8 %, c_T 65.6/94.2 %, b_T 69.4/96.1 %, θ_c
    71.4/96.3 %; χ²/dof 1.000 ± 0.052 (200 draws gave the same within a point or two).
    """
    from drivers.sim.css_optics import CHANNELS, CssOptics, css_truth

    truth = css_truth(seed=3, response="kelly")
    optics = CssOptics(truth)
    rng0 = np.random.default_rng(7)
    v = rng0.standard_normal((400, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    sun = np.concatenate([v, v, np.full((20, 3), np.nan)])
    dark = np.r_[np.zeros(800, bool), np.ones(20, bool)]
    channels = ("px_uv", "py_vis", "pz_ir")
    z: dict = {}
    chi2 = []
    for draw in range(DRAWS):
        rng = np.random.default_rng(1000 + draw)
        temp = rng.choice(np.arange(15.0, 35.1, 2.5), sun.shape[0])
        clean = optics.signals(np.nan_to_num(sun), np.where(dark, 0.0, 1.0)[:, None], temp)
        y = clean.copy()
        for t in np.unique(temp):
            at = temp == t
            y[at] += optics.noise_sd(clean[at], t) * rng.standard_normal(clean[at].shape)
        for c in channels:
            d = truth.diodes[CHANNELS.index(c)]
            fit = fit_diode(c, sun, y[:, CHANNELS.index(c)], temp, dark=dark)
            tu, tv = tilts_from_normal(c[:2], d.normal)
            true = {"scale": d.scale, "bias": d.bias, "tilt_u_deg": tu, "tilt_v_deg": tv, "kappa": d.kelly_kappa,
                    "fov_half_deg": d.fov_half_deg, "temp_coeff_per_c": d.temp_coeff_per_c,
                    "bias_temp_coeff_per_c": d.bias_temp_coeff}
            for name in fit.free:
                z.setdefault(name, []).append((fit.values[name] - true[name]) / fit.sd[name])
            chi2.append(fit.chi2_dof)
    report = {}
    for name, values in z.items():
        a = np.abs(np.array(values))
        report[name] = (np.mean(a < 1), np.mean(a < 2), a.size)
    assert set(report) >= {"scale", "bias", "tilt_u_deg", "tilt_v_deg", "kappa", "temp_coeff_per_c",
                           "bias_temp_coeff_per_c", "fov_half_deg"}
    for name, (one, two, count) in report.items():
        assert 0.60 <= one <= 0.76 and two >= 0.90, (name, one, two, count, report)
    assert np.mean(chi2) == pytest.approx(1.0, abs=0.05)
