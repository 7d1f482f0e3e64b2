"""The CSS attitude study (bench/css_study.py, `sunbench study css-attitude`): seed 000's LUT algorithm against the
least-squares estimator on the same simulated readings of a tumbling head in orbit.

The head is the simulator's default physical one (drivers/sim/css_optics.py, "fresnel": window and cap shadow), not
the fit's law; it is calibrated on the simulated bench first (a coarse sweep here, to keep the test short).
"""

import json

import numpy as np
import pytest
from clitools import invoke

from bench.css_study import angle_table, bench_calibration, compare_attitude, error_figures, orbit_readings
from drivers.sim.css_optics import css_truth
from drivers.sim.css_orbit import earth_angular_radius_deg, orbit_samples


@pytest.fixture(scope="module")
def head():
    truth = css_truth("CSS-STUDY", seed=1000)
    return truth, bench_calibration(truth, step_deg=10.0, around=6, repeats=2, seed=1)


@pytest.fixture(scope="module")
def result(head):
    truth, document = head
    return compare_attitude(truth, orbit_samples(0.5, 160, seed=3), document=document, seed=3)


def test_orbit_geometry():
    samples = orbit_samples(1, 360, altitude_km=660.0, beta_deg=0.0, seed=0)
    assert earth_angular_radius_deg(660.0) == pytest.approx(64.98, abs=0.01)
    # β = 0: the shadow spans 2·asin(R/(R+h)) of the circle's 360° less the 180° of the day side → 1 − 0.5 − ρ'/180
    eclipse = 1 - samples.sunlit.mean()
    assert eclipse == pytest.approx((180 - 2 * (90 - 64.98)) / 360, abs=0.01)
    np.testing.assert_allclose(np.linalg.norm(samples.sun_body, axis=1), 1.0)
    # the attitude is a rotation: the Sun–nadir angle in the body equals the orbit frame's
    u = np.radians(samples.argument_of_latitude_deg)
    assert np.allclose(np.sum(samples.sun_body * samples.earth_body, axis=1), -np.cos(u))


def test_least_squares_beats_the_thesis_lut_on_the_same_readings(result):
    for scene, block in result["scenes"].items():
        f = block["figures"]
        ls = f["least squares, albedo-aware"] if scene == "albedo" else f["least squares"]
        for lut in ("thesis LUT (EPD)", "thesis LUT (BPW)", "thesis LUT, calibrated tables (BPW)"):
            assert f[lut]["n"] == ls["n"] + ls["missing"] - f[lut]["missing"]
            assert ls["rms_deg"] < 0.5 * f[lut]["rms_deg"], (scene, lut, ls, f[lut])
            assert ls["p99_deg"] < f[lut]["p99_deg"], (scene, lut, ls, f[lut])


def test_albedo_aware_estimate_is_better_than_the_plain_one_with_albedo(result):
    f = result["scenes"]["albedo"]["figures"]
    assert f["least squares, albedo-aware"]["p50_deg"] < f["least squares"]["p50_deg"]
    # without albedo there is nothing to remove: the plain estimator is the one scored
    assert "least squares, albedo-aware" not in result["scenes"]["no albedo"]["figures"]


def test_error_figures_and_angle_table():
    e = np.array([1.0, 2.0, np.nan, 3.0])
    f = error_figures(e, flagged=[False, True, False, False])
    assert (f["n"], f["missing"], f["flagged"]) == (3, 1, 1)
    assert f["rms_deg"] == pytest.approx(np.sqrt(14 / 3))
    assert f["rms_determined_deg"] == pytest.approx(np.sqrt(10 / 2))
    table = angle_table({"m": e}, [70.0, 100.0, 100.0, 180.0], (65.0, 90.0, 180.0))
    assert table["bins"] == [[65.0, 90.0], [90.0, 180.0]]
    assert [c["n"] for c in table["m"]] == [1, 2] and table["m"][1]["missing"] == 1


def test_readings_see_the_earth_only_with_albedo(head):
    truth, _ = head
    samples = orbit_samples(0.2, 100, seed=5)
    lit = orbit_readings(truth, samples, albedo=0.3, seed=1)
    dark = orbit_readings(truth, samples, albedo=0.0, seed=1)
    vis = [1, 4, 7, 10, 13, 16]
    # the same noise draw: the visible diodes differ by the albedo only, never negative, somewhere large
    extra = lit.signals[:, vis] - dark.signals[:, vis]
    assert np.all(extra > -1e-9) and extra.max() > 1e-5


def test_cli_prints_the_comparison(head, tmp_path):
    _, document = head
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps(document))
    plots = tmp_path / "plots" / "attitude.html"
    r = invoke("study", "css-attitude", "--orbits", "0.2", "--samples-per-orbit", "100", "--cal", cal,
               "--plots", plots)
    assert r.exit_code == 0, r.output
    for text in ("albedo: angular error of the Sun", "no albedo: angular error of the Sun", "thesis LUT (EPD)",
                 "least squares, albedo-aware", "by the Sun–Earth angle"):
        assert text in r.output
    assert plots.is_file() and (plots.parent / "plotly.min.js").is_file()
    r = invoke("study", "css-attitude", "--orbits", "0.1", "--cal", cal, "--json")
    assert r.exit_code == 0
    data = json.loads(r.output)
    assert set(data["scenes"]) == {"albedo", "no albedo"}
    r = invoke("study", "css-attitude", "--response", "lambertian", "--cal", cal)
    assert r.exit_code == 2 and "lambertian" in r.output
