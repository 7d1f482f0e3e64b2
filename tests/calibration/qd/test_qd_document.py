"""The QD calibration document: JSON round trip, apply from the document alone, C header compiled and run."""

import copy
import json
import subprocess

import numpy as np
import pytest
from ccompiler import c_compiler
from qd_simulation import GLINT_ROW

from calibration.errors import CalibrationFormatError
from calibration.geometry import direction_vector
from calibration.models import calibration_from_dict
from calibration.qd.angles import angle_between_projections_deg
from calibration.qd.dark import subtract_dark
from calibration.qd.design import DEFAULT_QD
from calibration.qd.document import QD_FORMAT_VERSION, apply_document, validate_document
from calibration.qd.evaluation import METHODS
from calibration.qd.export import c_header
from calibration.qd.physical import invert_physical
from calibration.qd.spot import spot_position, spot_ratios


@pytest.mark.parametrize("method", METHODS)
def test_document_round_trips_through_json_and_applies_alone(method, outcome, bench_data):
    report = outcome.report(method)
    doc = json.loads(json.dumps(report.document))
    assert (doc["family"], doc["method"], doc["version"]) == ("qd", method, QD_FORMAT_VERSION)
    assert doc["dark"]["model"] == outcome.dark.kind and doc["design"]["eq21_length_m"] > 0
    assert doc["metrics"]["heldout"]["max_deg"] == pytest.approx(report.heldout.max_deg)
    for name, entry in doc["parameters"].items():
        assert entry["sd"] is not None, name  # every parameter carries its 1σ
    light = ~bench_data.dark
    light[GLINT_ROW] = False
    alpha, beta, zen, az = apply_document(doc, bench_data.currents_a[light], bench_data.temperature_c[light])
    err = angle_between_projections_deg(bench_data.alpha_deg[light], bench_data.beta_deg[light], alpha, beta)
    # zenith and azimuth are the direction (α, β): tan α = s_x / s_z, tan β = s_y / s_z
    s = direction_vector(zen, az)
    np.testing.assert_allclose(s[:, 0] / s[:, 2], np.tan(np.radians(alpha)), atol=1e-12)
    np.testing.assert_allclose(s[:, 1] / s[:, 2], np.tan(np.radians(beta)), atol=1e-12)
    # the document alone gives what the fitted model gives
    photo = subtract_dark(bench_data.currents_a[light], bench_data.temperature_c[light], outcome.dark)
    if method == "physical":
        assert err.max() < 0.1  # single readings, noise and dark current included
        a2, b2, _ = invert_physical(photo, report.model.parameters)
    else:
        assert np.all(np.isfinite(err))
        if method == "geometric":
            a2, b2 = report.model.apply(*spot_position(photo, DEFAULT_QD.eq21_length_m))  # eqs. 2.1–2.2
        else:
            a2, b2 = report.model.evaluate(*spot_ratios(photo))  # eqs. 2.1, 2.3
    np.testing.assert_allclose(alpha, a2, atol=1e-9)
    np.testing.assert_allclose(beta, b2, atol=1e-9)


def test_a_qd_document_is_not_mistaken_for_another(outcome):
    doc = outcome.document
    validate_document(doc)
    with pytest.raises(CalibrationFormatError):
        calibration_from_dict(doc)  # the CMOS loader refuses it (unknown method)
    for change in ({"family": "cmos"}, {"version": 99}, {"method": "seed003"}, {"format": "other"}):
        with pytest.raises(CalibrationFormatError):
            validate_document({**doc, **change})
    broken = copy.deepcopy(doc)
    next(iter(broken["parameters"].values()))["value"] = None
    with pytest.raises(CalibrationFormatError):
        validate_document(broken)
    broken = copy.deepcopy(doc)
    del broken["dark"]["quadrants"][0]
    with pytest.raises(CalibrationFormatError):
        apply_document(broken, np.ones((1, 4)) * 1e-6, 20.0)


def test_no_light_gives_nan_not_an_error(outcome):
    alpha, beta, zen, az = apply_document(outcome.document, np.zeros((2, 4)), [20.0, 25.0])
    assert all(np.isnan(v).all() for v in (alpha, beta, zen, az))


MAIN = r"""
#include <stdio.h>
#include "qd.h"
int main(void) {
    double c[4], t, a, b, z, az;
    while (scanf("%lf %lf %lf %lf %lf", &c[0], &c[1], &c[2], &c[3], &t) == 5) {
        int ok = sunbench_qd_angles(c, t, &a, &b) && sunbench_qd_sun_direction(c, t, &z, &az);
        if (ok) printf("1 %.17g %.17g %.17g %.17g\n", a, b, z, az); else printf("0 0 0 0 0\n");
    }
    return 0;
}
"""


@pytest.mark.parametrize("method", METHODS)
def test_compiled_header_matches_apply(method, outcome, bench_data, tmp_path):
    compiler = c_compiler()
    doc = outcome.report(method).document
    (tmp_path / "qd.h").write_text(c_header(doc, provenance={"run": "test */ run", "heldout": "0.02°"}))
    (tmp_path / "main.c").write_text(MAIN)
    exe = tmp_path / "qd"
    build = subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-o", str(exe),
                            str(tmp_path / "main.c"), "-lm"], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    light = np.flatnonzero(~bench_data.dark)
    rng = np.random.default_rng(0)
    pick = rng.choice(light, 200, replace=False)
    currents = np.concatenate([bench_data.currents_a[pick], np.zeros((1, 4)), [[1e-6, 0, 0, 0]]])
    temps = np.concatenate([bench_data.temperature_c[pick] + rng.uniform(-15, 15, pick.size), [20.0, 20.0]])
    text = "".join(" ".join(repr(float(v)) for v in (*c, t)) + "\n" for c, t in zip(currents, temps))
    run = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True)
    got = np.array([line.split() for line in run.stdout.splitlines()], dtype=float)
    alpha, beta, zen, az = apply_document(doc, currents, temps)
    ok = np.isfinite(alpha)
    assert got.shape == (currents.shape[0], 5)
    np.testing.assert_array_equal(got[:, 0] == 1, ok)  # the same readings have no answer
    np.testing.assert_allclose(got[ok, 1], alpha[ok], atol=1e-9)
    np.testing.assert_allclose(got[ok, 2], beta[ok], atol=1e-9)
    np.testing.assert_allclose(got[ok, 3], zen[ok], atol=1e-9)
    np.testing.assert_allclose(np.mod(got[ok, 4] - az[ok] + 180, 360) - 180, 0.0, atol=1e-9)
    assert not ok[-2]  # no light
