"""The C header gives the firmware the same directions as the library: compiled and run here."""

import subprocess

import numpy as np
import pytest
from ccompiler import c_compiler

from calibration.export import c_header
from calibration.geometry import wrap_deg
from calibration.models import METHODS, fit_calibration
from calibration.synthetic import synthetic_bench_data

MAIN = r"""
#include <stdio.h>
#include "calibration.h"
int main(void) {
    double x, y, zenith, azimuth;
    while (scanf("%lf %lf", &x, &y) == 2) {
        sunbench_sun_direction(x, y, &zenith, &azimuth);
        printf("%.17g %.17g\n", zenith, azimuth);
    }
    return 0;
}
"""


@pytest.fixture(scope="module")
def data():
    return synthetic_bench_data(noise_px=0.02, seed=11)


@pytest.mark.parametrize("method", list(METHODS))
def test_compiled_header_matches_apply(method, data, tmp_path):
    compiler = c_compiler()
    calibration = fit_calibration(data, method)
    (tmp_path / "calibration.h").write_text(c_header(calibration, sensor_id="SIM-0001"))
    (tmp_path / "main.c").write_text(MAIN)
    exe = tmp_path / "direction"
    build = subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-o", str(exe),
                            str(tmp_path / "main.c"), "-lm"], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    rng = np.random.default_rng(0)
    x = np.concatenate([data.x_px, rng.uniform(90, 550, 300)])
    y = np.concatenate([data.y_px, rng.uniform(20, 460, 300)])
    run = subprocess.run([str(exe)], input="".join(f"{float(a)!r} {float(b)!r}\n" for a, b in zip(x, y)),
                         capture_output=True, text=True, check=True)
    got = np.array([line.split() for line in run.stdout.splitlines()], dtype=float)
    zenith, azimuth = calibration.apply(x, y)
    assert got.shape == (x.size, 2)
    np.testing.assert_allclose(got[:, 0], zenith, atol=1e-9)
    np.testing.assert_allclose(wrap_deg(got[:, 1] - azimuth), 0.0, atol=1e-9)


def test_header_names_method_and_sensor(data):
    text = c_header(fit_calibration(data, "seed003-tilt"), sensor_id="NORBI-07")
    assert "#ifndef SUNBENCH_CALIBRATION_NORBI_07_H" in text
    assert '#define SB_CALIBRATION_METHOD "seed003-tilt"' in text
    assert "SB_TILT_DEG" in text and "SB_ZENITH_COEF[7]" in text
