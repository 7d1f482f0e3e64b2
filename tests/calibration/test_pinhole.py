"""The physical pinhole model, against the ideal pinhole (seed 003 eq. 6) and the research note's numbers."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from calibration.design import DEFAULT_SENSOR
from calibration.geometry import angular_error_deg
from calibration.pinhole import (
    PinholeBuild,
    direction_from_spot,
    incidence_from_radial_offset,
    radial_offset_mm,
    spot_from_direction,
)

PITCH = DEFAULT_SENSOR.pixel_pitch_mm


def test_ideal_pinhole_is_seed003_eq6():
    build = PinholeBuild(x0_px=320.0, y0_px=240.0, gap_mm=1.37)
    x, y = spot_from_direction(45.0, 0.0, build, PITCH)
    # θ = arctan(r / L): at 45° the spot is L away, opposite the sun (the pinhole inverts the image)
    assert x == pytest.approx(320.0 - 1.37 / PITCH)
    assert y == pytest.approx(240.0)
    x, y = spot_from_direction(30.0, 90.0, build, PITCH)
    assert (x, y) == (pytest.approx(320.0), pytest.approx(240.0 - 1.37 * np.tan(np.radians(30)) / PITCH))


def test_glass_term_is_snell_refraction():
    # trace the ray by hand: air gap at θ, glass at asin(sin θ / n)
    theta, gap, glass, n = 50.0, 0.9, 0.45, 1.52
    refracted = np.arcsin(np.sin(np.radians(theta)) / n)
    expected = gap * np.tan(np.radians(theta)) + glass * np.tan(refracted)
    assert radial_offset_mm(theta, gap, glass, n) == pytest.approx(expected, rel=1e-14)
    back = incidence_from_radial_offset(np.array([0.0, expected, 3.0]), gap, glass, n)
    assert back[0] == 0.0
    assert back[1] == pytest.approx(theta, abs=1e-10)
    assert radial_offset_mm(back[2], gap, glass, n) == pytest.approx(3.0, rel=1e-12)


@pytest.mark.parametrize("mirrored", [False, True])
def test_forward_and_inverse_agree(mirrored):
    build = PinholeBuild(x0_px=331.2, y0_px=228.9, gap_mm=1.05, glass_mm=0.5, glass_index=1.52,
                         tilt_x_deg=0.4, tilt_y_deg=-0.7, rotation_deg=-2.3, mirrored=mirrored)
    rng = np.random.default_rng(1)
    zen, az = rng.uniform(0, 70, 2000), rng.uniform(0, 360, 2000)
    x, y = spot_from_direction(zen, az, build, PITCH)
    z2, a2 = direction_from_spot(x, y, build, PITCH)
    assert angular_error_deg(zen, az, z2, a2).max() < 1e-9


def test_refraction_error_of_a_plain_tan_model_matches_the_research_note():
    # anchors-sunsensors §2.2 [M] (refr.py): L_total = 1.37 mm, n = 1.5, θ ≤ 62°; with t = 0.1/0.3/0.5 mm a
    # pure pinhole model with best-fit f leaves 0.13/0.41/0.74° RMS (max 0.29/0.94/1.73°); a 6th-order θ(r)
    # absorbs it to ≈ 0.002° RMS.
    theta = np.linspace(0, 62, 63)
    for glass, rms, worst in [(0.1, 0.126, 0.287), (0.3, 0.408, 0.943), (0.5, 0.741, 1.734)]:
        r = radial_offset_mm(theta, 1.37 - glass, glass, 1.5) / PITCH
        f = least_squares(lambda p: np.degrees(np.arctan(r / p[0])) - theta, [150.0]).x[0]  # noqa: B023 - called at once
        err = np.degrees(np.arctan(r / f)) - theta
        assert np.sqrt(np.mean(err**2)) == pytest.approx(rms, abs=1e-3)
        assert np.abs(err).max() == pytest.approx(worst, abs=1e-3)
        poly = np.polyval(np.polyfit(r, theta, 6), r) - theta
        assert np.sqrt(np.mean(poly**2)) < 0.003


def test_detector_tilt_error_matches_the_research_note():
    # anchors-sunsensors §2.3 [M] (tilt.py): a 0.12° detector tilt, after re-centring on the normal-incidence
    # spot and reading θ = arctan(r / L), gives ±0.014/0.049/0.09° at θ = 20/40/60°, ∝ cos(φ − φ_tilt).
    build = PinholeBuild(x0_px=0.0, y0_px=0.0, gap_mm=1.37, tilt_x_deg=0.12)
    x0, y0 = spot_from_direction(0.0, 0.0, build, PITCH)
    for theta, amplitude in [(20, 0.014), (40, 0.049), (60, 0.09)]:
        az = np.arange(0.0, 360.0, 45.0)
        x, y = spot_from_direction(np.full(8, theta), az, build, PITCH)
        err = np.degrees(np.arctan(np.hypot(x - x0, y - y0) * PITCH / 1.37)) - theta
        assert np.abs(err).max() == pytest.approx(amplitude, abs=1.5e-3)
        assert err[0] == pytest.approx(-err[4], abs=2e-3)  # mirror-symmetric for opposite azimuths (Fig. 4.7)
        assert abs(err[2]) < 2e-3  # no error across the tilt


def test_build_validation():
    with pytest.raises(ValueError, match="gap_mm"):
        PinholeBuild(gap_mm=0.0)
    with pytest.raises(ValueError, match="glass_index"):
        PinholeBuild(glass_index=0.9)


def test_non_round_aperture_stretches_the_offset_and_inverts_exactly():
    round_ = PinholeBuild(x0_px=320.0, y0_px=240.0, gap_mm=1.2, glass_mm=0.3)
    oval = PinholeBuild(x0_px=320.0, y0_px=240.0, gap_mm=1.2, glass_mm=0.3, aperture_c=0.004, aperture_s=-0.002)
    zen, az = np.full(4, 40.0), np.array([0.0, 45.0, 90.0, 135.0])
    x0, y0 = spot_from_direction(zen, az, round_, PITCH)
    x1, y1 = spot_from_direction(zen, az, oval, PITCH)
    ratio = np.hypot(x1 - 320, y1 - 240) / np.hypot(x0 - 320, y0 - 240)
    # detector azimuths of the spot are 180°, 225°, 270°, 315°: cos 2φ = 1, 0, −1, 0 and sin 2φ = 0, 1, 0, −1
    np.testing.assert_allclose(ratio, [1.004, 0.998, 0.996, 1.002], atol=1e-12)
    rng = np.random.default_rng(2)
    zen, az = rng.uniform(0, 65, 500), rng.uniform(0, 360, 500)
    back = direction_from_spot(*spot_from_direction(zen, az, oval, PITCH), oval, PITCH)
    assert angular_error_deg(zen, az, *back).max() < 1e-9
