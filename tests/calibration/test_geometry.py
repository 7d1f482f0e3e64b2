"""Geometry of seed 003: eqs. 7, 8, 10, 12–15, against the thesis' own (derived) numbers."""

import numpy as np
import pytest

from calibration.geometry import (
    angular_error_deg,
    azimuth_measured_deg,
    combined_tilt,
    direction_vector,
    incidence_from_stage_angle,
    split_tilt,
    spot_radius_px,
    tilt_along_azimuth,
    wrap_deg,
    zenith_azimuth_from_vector,
)

# seed 003 digest §2.6, [derived] from eq. 8 with d = 136.2 mm
EQ8_TABLE = {
    710.0: [0, 11.902, 23.711, 35.342, 46.730, 57.831, 68.620],
    7100.0: [0, 10.191, 20.375, 30.548, 40.703, 50.836, 60.943],
}


@pytest.mark.parametrize("source_mm", sorted(EQ8_TABLE))
def test_eq8_reproduces_the_thesis_table(source_mm):
    omega = np.arange(0, 61, 10)
    theta = incidence_from_stage_angle(omega, 136.2, source_mm)
    np.testing.assert_allclose(theta, EQ8_TABLE[source_mm], atol=1e-3)


def test_eq8_scalar_sign_and_limits():
    assert incidence_from_stage_angle(0.0, 136.2, 710.0) == 0.0
    assert incidence_from_stage_angle(-30.0, 136.2, 710.0) == pytest.approx(-35.342, abs=1e-3)
    # no lever arm: the table angle is the incidence angle
    np.testing.assert_allclose(incidence_from_stage_angle([5.0, 45.0, 80.0], 0.0, 710.0), [5.0, 45.0, 80.0])
    # a far source makes the parallax vanish
    assert incidence_from_stage_angle(40.0, 136.2, 1e9) == pytest.approx(40.0, abs=1e-5)
    with pytest.raises(ValueError):
        incidence_from_stage_angle(10.0, 136.2, 0.0)


def test_direction_vector_and_inverse_round_trip():
    rng = np.random.default_rng(0)
    zen, az = rng.uniform(0, 89, 500), rng.uniform(0, 360, 500)
    n = direction_vector(zen, az)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(direction_vector(90.0, 90.0), [0.0, 1.0, 0.0], atol=1e-15)
    z2, a2 = zenith_azimuth_from_vector(n)
    np.testing.assert_allclose(z2, zen, atol=1e-10)
    np.testing.assert_allclose(wrap_deg(a2 - az), 0.0, atol=1e-9)


def test_angular_error_eq13():
    assert angular_error_deg(0.0, 0.0, 90.0, 0.0) == pytest.approx(90.0)
    assert angular_error_deg(30.0, 10.0, 30.0, 190.0) == pytest.approx(60.0)
    # the azimuth is irrelevant at normal incidence
    assert angular_error_deg(0.0, 0.0, 0.0, 123.0) == pytest.approx(0.0, abs=1e-12)
    # tiny errors keep their precision (plain arccos would return ~1e-6 of noise here)
    assert angular_error_deg(45.0, 0.0, 45.0 + 1e-7, 0.0) == pytest.approx(1e-7, rel=1e-6)
    # across the 0/360 seam
    assert angular_error_deg(90.0, 359.5, 90.0, 0.5) == pytest.approx(1.0)


def test_eq10_quadrants_match_the_thesis():
    # digest §2.5: spot toward −y ⇒ 0°, +x ⇒ 90°, +y ⇒ 180°, −x ⇒ 270°
    x = np.array([0.0, 5.0, 0.0, -5.0])
    y = np.array([-5.0, 0.0, 5.0, 0.0])
    np.testing.assert_allclose(azimuth_measured_deg(x + 100, y + 50, 100, 50), [0, 90, 180, 270])
    # eq. 10 as written (arctan + 90° / + 270°) on a generic point of each half plane
    for dx, dy in [(3.0, 2.0), (3.0, -2.0), (-3.0, 2.0), (-3.0, -2.0)]:
        thesis = np.degrees(np.arctan(dy / dx)) + (90.0 if dx >= 0 else 270.0)
        assert azimuth_measured_deg(dx, dy, 0.0, 0.0) == pytest.approx(thesis)


def test_eq7_radius():
    assert spot_radius_px(103.0, 54.0, 100.0, 50.0) == pytest.approx(5.0)


def test_eq14_15_tilt_composition():
    tilt, az = combined_tilt(0.12, 0.0)
    assert tilt == pytest.approx(0.12) and az == pytest.approx(0.0)
    tilt, az = combined_tilt(0.0, -0.1)
    assert tilt == pytest.approx(0.1) and az == pytest.approx(270.0)
    tilt, az = combined_tilt(0.3, 0.4)
    assert np.tan(np.radians(tilt)) ** 2 == pytest.approx(np.tan(np.radians(0.3)) ** 2 + np.tan(np.radians(0.4)) ** 2)
    # θ*(0°) = α and θ*(90°) = β, θ* vanishes across the tilt direction (digest §2.10)
    assert tilt_along_azimuth(0.0, tilt, az) == pytest.approx(0.3, abs=2e-5)
    assert tilt_along_azimuth(90.0, tilt, az) == pytest.approx(0.4, abs=2e-5)
    assert tilt_along_azimuth(az + 90.0, tilt, az) == pytest.approx(0.0, abs=1e-12)
    alpha, beta = split_tilt(tilt, az)
    assert (alpha, beta) == (pytest.approx(0.3), pytest.approx(0.4))
