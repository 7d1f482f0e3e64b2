"""Seed 003's procedure: its grid (§4.2) and the tilt stage's estimates (§4.4–4.5, eqs. 14–15)."""

import numpy as np
import pytest

from calibration.geometry import combined_tilt, tilt_along_azimuth
from calibration.procedure import (
    SEED003_AZIMUTHS_DEG,
    SEED003_ZENITH_STAGE_DEG,
    centre_crossing_deg,
    grid_azimuths_deg,
    grid_zeniths_deg,
    tilt_harmonic_deg,
)


def test_the_seed003_grid_is_8_azimuths_by_7_zeniths():
    assert SEED003_AZIMUTHS_DEG == (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0)
    assert SEED003_ZENITH_STAGE_DEG == (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
    np.testing.assert_allclose(grid_azimuths_deg(90.0), [0, 90, 180, 270])
    assert grid_azimuths_deg(7.0).size == 52 and grid_azimuths_deg(7.0)[-1] == 357.0
    np.testing.assert_allclose(grid_zeniths_deg(50.0, 25.0), [0, 25, 50])


@pytest.mark.parametrize("call", [lambda: grid_azimuths_deg(0.0), lambda: grid_zeniths_deg(60.0, 0.0),
                                  lambda: grid_zeniths_deg(-1.0, 10.0)])
def test_the_grid_refuses_bad_steps(call):
    with pytest.raises(ValueError):
        call()


def test_centre_crossing_interpolates_along_the_spot_motion():
    # the spot moves 4 px per degree along +x; the centre lies a quarter of the way from −1° to +1°
    assert centre_crossing_deg([100.0, 50.0], [108.0, 50.0], [102.0, 50.0], 1.0) == pytest.approx(-0.5)
    # off the line: its projection counts
    assert centre_crossing_deg([100.0, 50.0], [108.0, 50.0], [106.0, 55.0], 1.0) == pytest.approx(0.5)
    # vectorised over azimuths; a spot that did not move has no crossing
    out = centre_crossing_deg([[100.0, 50.0], [10.0, 10.0]], [[108.0, 50.0], [10.0, 10.0]], [104.0, 50.0], 2.0)
    assert out[0] == pytest.approx(0.0) and np.isnan(out[1])
    with pytest.raises(ValueError, match="probe_deg"):
        centre_crossing_deg([0, 0], [1, 0], [0, 0], 0.0)


def test_tilt_harmonic_recovers_the_eq15_tilt_and_the_non_parallelism():
    alpha, beta, mean = 0.12, -0.08, 0.47  # seed 003: tilt ≤ 0.12°, 0.47° non-parallelism
    azimuth = np.array(SEED003_AZIMUTHS_DEG)
    tilt, tilt_azimuth = combined_tilt(alpha, beta)  # eq. 14
    offset = mean + tilt_along_azimuth(azimuth, tilt, tilt_azimuth)  # eq. 15
    m, a, b = tilt_harmonic_deg(azimuth, offset)
    assert (m, a, b) == pytest.approx((mean, alpha, beta), abs=1e-5)


def test_tilt_harmonic_needs_three_azimuths():
    with pytest.raises(ValueError, match="3 distinct"):
        tilt_harmonic_deg([0.0, 90.0, 360.0], [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="one length"):
        tilt_harmonic_deg([0.0, 90.0, 180.0], [0.1, 0.2])
