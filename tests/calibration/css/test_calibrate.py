"""Bench data, head calibration, held-out scoring and the JSON document of the CSS family (calibration.css).

Bench runs come from the head's simulated physics, drivers/sim/css_optics.py (its own, never the fit's forward
model): the default ``fresnel`` law (cosine × window transmittance × the package cap's shadow; the thermopile's
datasheet field curve), which the calibration's Kelly model cannot hold exactly, and the ``kelly`` law, which it can.
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from calibration.css.calibrate import (
    CSS_FORMAT_VERSION,
    FORMAT,
    apply_css_document,
    calibrate_css,
    css_document,
    head_model_from_document,
    validate_css_document,
)
from calibration.css.data import CssBenchData
from calibration.css.head import CHANNELS, COLUMNS
from calibration.errors import BenchDataError, CalibrationFormatError


def unit(zenith_deg, azimuth_deg):
    th, ph = np.radians(zenith_deg), np.radians(azimuth_deg)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)


def bench_run(law: str, seed: int = 11, *, zenith_step=10.0, azimuth_step=15.0):
    """A bench run of a head from css_optics: a zenith × azimuth grid twice (the second pass in reverse order),
    off-grid check directions, ten dark readings before and after, the head's temperature drifting 20–30 °C as a
    slow swing over the run (not in step with the sweep), each reading with the simulator's own noise."""
    from drivers.sim.css_optics import CssOptics, css_truth

    truth = css_truth(seed=seed, response=law)
    optics = CssOptics(truth)
    rng = np.random.default_rng(seed)
    zen, az = np.meshgrid(np.arange(0, 180.1, zenith_step), np.arange(0, 360, azimuth_step), indexing="ij")
    zen, az = zen.ravel(), az.ravel()
    keep = ((zen > 0) & (zen < 180)) | (az == 0)
    zen, az = zen[keep], az[keep]
    zc, ac = np.meshgrid(np.arange(zenith_step / 2, 180, 2 * zenith_step), np.arange(azimuth_step / 2, 360,
                                                                                    3 * azimuth_step), indexing="ij")
    nd = 10
    z_all = np.r_[np.full(nd, np.nan), zen, zc.ravel(), zen[::-1], np.full(nd, np.nan)]
    a_all = np.r_[np.full(nd, np.nan), az, ac.ravel(), az[::-1], np.full(nd, np.nan)]
    check = np.r_[np.zeros(nd + zen.size, bool), np.ones(zc.size, bool), np.zeros(zen.size + nd, bool)]
    repeat = np.r_[np.zeros(nd + zen.size + zc.size, int), np.ones(zen.size + nd, int)]
    dark = np.isnan(z_all)
    phase = np.linspace(0.0, 1.0, z_all.size)
    temp = 25.0 + 5.0 * np.sin(2 * np.pi * 1.3 * phase) + 0.05 * rng.standard_normal(z_all.size)
    sun = unit(np.nan_to_num(z_all), np.nan_to_num(a_all))
    clean = optics.signals(sun, np.where(dark, 0.0, 1.0)[:, None], temp)
    noise = np.stack([optics.noise_sd(clean[i], temp[i]) for i in range(temp.size)])
    signals = clean + noise * rng.standard_normal(clean.shape)
    data = CssBenchData(z_all, a_all, signals, temp, repeat=repeat, dark=dark, check=check, sensor_id=truth.serial)
    return truth, optics, data


@pytest.fixture(scope="module")
def fresnel():
    truth, optics, data = bench_run("fresnel")
    return truth, optics, data, calibrate_css(data)


@pytest.fixture(scope="module")
def kelly():
    truth, optics, data = bench_run("kelly", seed=5)
    return truth, optics, data, calibrate_css(data)


# --- bench data ----------------------------------------------------------------------------------------------------


def test_bench_data_validates_and_names_the_row_and_column():
    sig = np.ones((3, 18))
    ok = CssBenchData([10, 20, 30], [0, 0, 0], sig, [25, 25, 25])
    assert ok.channels == CHANNELS and ok.columns == COLUMNS and len(ok) == 3
    assert ok.row_id.tolist() == [1, 2, 3] and ok.sun_vectors.shape == (3, 3)
    with pytest.raises(BenchDataError, match="18 channels") as err:
        CssBenchData([10], [0], np.ones((1, 5)), [25])
    assert err.value.column == "signals"
    with pytest.raises(BenchDataError, match="unknown channel") as err:
        CssBenchData([10], [0], np.ones((1, 1)), [25], channels=("px_red",))
    assert err.value.column == "px_red"
    with pytest.raises(BenchDataError, match="head's order"):
        CssBenchData([10], [0], np.ones((1, 2)), [25], channels=("py_uv", "px_uv"))
    bad = sig.copy()
    bad[1, 4] = np.inf
    with pytest.raises(BenchDataError, match="row 2 has an infinite py_vis_a reading") as err:
        CssBenchData([10, 20, 30], [0, 0, 0], bad, [25, 25, 25])
    assert err.value.row == 1 and err.value.column == "py_vis_a"
    empty = sig.copy()
    empty[2] = np.nan
    with pytest.raises(BenchDataError, match="row 3 has no reading") as err:
        CssBenchData([10, 20, 30], [0, 0, 0], empty, [25, 25, 25])
    assert err.value.row == 2
    with pytest.raises(BenchDataError, match="0…180") as err:
        CssBenchData([10, 190, 30], [0, 0, 0], sig, [25, 25, 25])
    assert err.value.row == 1 and err.value.column == "zenith_deg"
    with pytest.raises(BenchDataError, match="both dark and check"):
        CssBenchData([10, 20, 30], [0, 0, 0], sig, [25, 25, 25], dark=[1, 0, 0], check=[1, 0, 0])
    with pytest.raises(BenchDataError, match="no temperature") as err:
        CssBenchData([10, 20, 30], [0, 0, 0], sig, [25, np.nan, 25])
    assert err.value.column == "temperature_c"
    dark_ok = CssBenchData([np.nan, 20, 30], [np.nan, 0, 0], sig, [25, 25, 25], dark=[1, 0, 0])
    assert np.all(np.isnan(dark_ok.sun_vectors[0]))
    partial = sig.copy()
    partial[0, :3] = np.nan  # a missing reading of some channels is allowed
    CssBenchData([10, 20, 30], [0, 0, 0], partial, [25, 25, 25])


def test_bench_data_from_columns_and_subsets():
    cols = {"px_uv_a": [1e-6, 2e-6], "pz_ir_v": [1e-4, 2e-4], "other": [0, 0]}
    data = CssBenchData.from_columns(cols, [10, 20], [0, 90], [25, 26], sensor_id="X")
    assert data.channels == ("px_uv", "pz_ir") and data.signal("pz_ir").tolist() == [1e-4, 2e-4]
    assert data.subset(np.array([False, True])).signal("px_uv").tolist() == [2e-6]
    assert data.select_channels(["pz_ir"]).channels == ("pz_ir",)
    assert data.temperature_span_c == pytest.approx(1.0)
    with pytest.raises(BenchDataError, match="no channel column"):
        CssBenchData.from_columns({"x": [1]}, [10], [0], [25])


# --- the default (fresnel) head: outside the model's class -----------------------------------------------------------


def test_fresnel_head_scale_bias_and_normal_within_stated_tolerances(fresnel):
    """Stated tolerances for a head whose detectors the Kelly model does not describe exactly (the cap's shadow,
    the window's transmittance, the thermopile's datasheet curve): scale within 1 % (UV), 3.5 % (visible), 15 %
    (thermopile, whose field curve is far from any Kelly law); bias within 0.1 % of the scale (photodiodes), 1 %
    (thermopile); the normal within 1.5°. Achieved: scale UV 0.01–0.3 %, visible 0.05–2.3 %, thermopile 4.9–11.3 %;
    bias ≤ 0.0001 % of the scale (photodiodes), ≤ 0.46 % (thermopiles); normals 0.04–1.3° off."""
    truth, _, _, out = fresnel
    tolerance = {"uv": (0.01, 1e-3), "vis": (0.035, 1e-3), "ir": (0.15, 1e-2)}
    assert out.faulty == {}
    for c, fit in out.fits.items():
        d = truth.diode(c)
        scale_tol, bias_tol = tolerance[c.split("_")[1]]
        assert fit.values["scale"] / d.scale - 1 == pytest.approx(0.0, abs=scale_tol), c
        assert abs(fit.values["bias"] - d.bias) < bias_tol * d.scale, c
        angle = np.degrees(np.arccos(np.clip(fit.parameters.normal @ d.normal, -1, 1)))
        assert angle < 1.5, (c, angle)


def test_fresnel_head_held_out_figures_are_honest(fresnel):
    """Held out, the detectors' residuals are larger than at the directions they were fitted to: the figures are not
    flattered, and the model's misfit is said in words. Achieved: held-out/fitted residual RMS > 1 for 18 of 18
    detectors (median 1.07). The Sun's direction: 2.0° RMS held out over 343 readings (477 flagged degenerate or
    ambiguous: with a model error of 1–4 % of the scale the mirror direction across a faint face often fits as
    well), 2.8° at the fitted directions (one wrong-mirror reading of 26° among them); normalised RMS 1.13, which the
    document's uncertainty scale carries to every later estimate."""
    _, _, _, out = fresnel
    ratios = [scores["heldout"]["rms"] / scores["at_nodes"]["rms"] for scores in out.heldout["channels"].values()]
    assert np.median(ratios) > 1.0
    assert np.mean(np.array(ratios) > 1.0) >= 0.6
    sun = out.heldout["sun"]
    assert sun["heldout"]["n_points"] > 100 and sun["heldout"]["rms_deg"] < 10.0
    assert sun["heldout"]["n_degenerate"] > 0
    assert any("does not describe this detector to its noise" in w for w in out.warnings)
    assert any("held-out reading(s) light fewer than two non-coplanar faces" in w for w in out.warnings)
    # the document widens the estimator's stated uncertainty by what held-out directions showed
    assert out.document["uncertainty_scale"] == pytest.approx(max(1.0, sun["heldout"]["normalised_rms"]))


# --- the in-class (kelly) head -------------------------------------------------------------------------------------


def test_kelly_head_is_calibrated_to_its_noise_and_scored_honestly(kelly):
    truth, _, _, out = kelly
    assert out.faulty == {}
    for c, fit in out.fits.items():
        d = truth.diode(c)
        assert abs(fit.values["scale"] - d.scale) < 5 * fit.sd["scale"], c
        assert 0.8 < fit.chi2_dof < 1.25, (c, fit.chi2_dof)
    sun = out.heldout["sun"]
    assert sun["heldout"]["rms_deg"] < 0.1
    assert 0.8 < sun["heldout"]["normalised_rms"] < 1.25
    assert sun["check"]["n_points"] > 20 and sun["check"]["rms_deg"] < 0.2
    for c, scores in out.heldout["channels"].items():
        assert 0.8 < scores["heldout"]["rms_normalised"] < 1.3, (c, scores)


def test_document_round_trips_through_json_and_applies_alone(kelly):
    truth, optics, _, out = kelly
    doc = out.document
    assert doc["format"] == FORMAT and doc["version"] == CSS_FORMAT_VERSION and doc["family"] == "css"
    assert doc["reference_temperature_c"] == 25.0 and doc["response"] == "kelly"
    assert set(doc["diodes"]) == set(CHANNELS)
    entry = doc["diodes"]["py_vis"]
    assert entry["valid"] and entry["unit"] == "a"
    assert set(entry["parameters"]) == {"scale", "bias", "tilt_u_deg", "tilt_v_deg", "kappa", "fov_half_deg",
                                        "temp_coeff_per_c", "bias_temp_coeff_per_c"}
    assert entry["parameters"]["scale"]["sd"] > 0 and entry["noise"]["sigma0"] > 0
    assert len(entry["covariance"]["names"]) == len(entry["covariance"]["matrix"])
    restored = json.loads(json.dumps(doc))
    validate_css_document(restored)
    head = head_model_from_document(restored)
    assert head.channels == out.head.channels
    # new readings, never on the bench's grid, through the document alone
    rng = np.random.default_rng(99)
    v = rng.standard_normal((300, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    clean = optics.signals(v, 1.0, 27.0)
    y = clean + optics.noise_sd(clean, 27.0) * rng.standard_normal(clean.shape)
    order = list(reversed(CHANNELS))  # any column order, named
    est = apply_css_document(restored, y[:, ::-1], order, 27.0)
    ok = ~est.degenerate
    err = np.degrees(np.arccos(np.clip(np.sum(est.vector[ok] * v[ok], axis=1), -1, 1)))
    assert ok.mean() > 0.9 and np.sqrt(np.mean(err**2)) < 0.1
    # the document's held-out uncertainty scale widens the estimator's own 1σ
    from calibration.css.estimate import estimate_sun

    plain = estimate_sun(head, y, 27.0)
    assert restored["uncertainty_scale"] >= 1.0
    assert est.sigma_deg[ok] == pytest.approx(plain.sigma_deg[ok] * restored["uncertainty_scale"], rel=1e-9)


def test_faulty_channels_are_excluded_from_the_head_with_a_warning(kelly):
    _, _, data, _ = kelly
    sig = data.signals.copy()
    k_stuck, k_dead, k_sat = CHANNELS.index("px_vis"), CHANNELS.index("my_uv"), CHANNELS.index("pz_vis")
    sig[:, k_stuck] = 3.2e-4
    rng = np.random.default_rng(1)
    sig[:, k_dead] = 5e-11 + 3e-11 * rng.standard_normal(len(data))
    sig[:, k_sat] = np.minimum(sig[:, k_sat], 1e-5)  # latched near the rail over most of its lit range
    broken = CssBenchData(data.zenith_deg, data.azimuth_deg, sig, data.temperature_c, repeat=data.repeat,
                          dark=data.dark, check=data.check, sensor_id=data.sensor_id)
    out = calibrate_css(broken, folds=2)
    assert out.faulty == {"px_vis": "stuck", "my_uv": "dead", "pz_vis": "saturated"}
    assert "px_vis" not in out.head.channels and len(out.head.channels) == 15
    text = " ".join(out.warnings)
    assert "px_vis: every reading is 0.00032 A — a stuck channel" in text
    assert "my_uv: the readings do not change with the Sun's direction — a stuck or dead diode" in text
    assert "pz_vis:" in text and "saturated" in text
    assert "px_vis is excluded from the head's calibration (stuck)" in text
    doc = out.document
    assert doc["diodes"]["px_vis"] == {**doc["diodes"]["px_vis"], "valid": False, "fault": "stuck"}
    assert "parameters" not in doc["diodes"]["px_vis"]
    est = apply_css_document(doc, sig[~data.dark][:50], CHANNELS, 25.0)
    assert est.used[:, list(est.channels).index("py_vis")].any() and "px_vis" not in est.channels


def test_power_law_response_is_an_option(kelly):
    _, _, data, _ = kelly
    out = calibrate_css(data.select_channels(["px_uv", "py_uv", "pz_uv", "mx_uv", "my_uv", "mz_uv"]),
                        response="power", folds=2)
    assert out.response == "power" and out.document["response"] == "power"
    assert "power" in out.document["diodes"]["px_uv"]["parameters"]
    assert out.heldout["sun"]["heldout"]["n_points"] > 100


# --- the document's checks -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("change, message", [
    (lambda d: d.update(format="sunbench.calibration"), "not a CSS calibration"),
    (lambda d: d.update(version=2), "version 2 is not supported"),
    (lambda d: d.update(response="cosine"), "unknown response law 'cosine'"),
    (lambda d: d.update(reference_temperature_c=20.0), "reference_temperature_c must be 25.0"),
    (lambda d: d["diodes"].update(px_red={"valid": True}), "unknown channel 'px_red'"),
    (lambda d: d["diodes"]["px_uv"]["parameters"].pop("kappa"), "diode px_uv: parameter `kappa` missing"),
    (lambda d: d["diodes"]["px_uv"]["parameters"]["scale"].update(value=None),
     "diode px_uv: parameter `scale` must be a finite number"),
    (lambda d: d["diodes"]["py_ir"]["noise"].update(sigma0=-1.0), "diode py_ir: noise `sigma0` is negative"),
    (lambda d: d["diodes"]["pz_vis"].pop("noise"), "diode pz_vis: no \"noise\" model"),
    (lambda d: d.update(uncertainty_scale=0.5), "uncertainty_scale must be at least 1"),
    (lambda d: [e.update(valid=False) for e in d["diodes"].values()], "without a valid diode"),
])
def test_validate_names_the_problem(kelly, change, message):
    doc = copy.deepcopy(kelly[3].document)
    change(doc)
    with pytest.raises(CalibrationFormatError, match=message):
        validate_css_document(doc)


def test_css_document_from_fits_alone(kelly):
    out = kelly[3]
    doc = css_document(out.fits, sensor_id="CSS-X", response="kelly")
    assert doc["sensor_id"] == "CSS-X" and doc["heldout"] is None and doc["uncertainty_scale"] == 1.0
    validate_css_document(doc)
