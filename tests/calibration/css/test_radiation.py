"""Planck, Stefan–Boltzmann, Sun and Earth, and eqs 3.1–3.2 of seed 000 (calibration.css.radiation).

Reference numbers are CODATA constants and the thesis' / digest's printed values, typed in here; nothing below
is a number computed by the code under test and pasted back.
"""

import numpy as np
import pytest
from scipy.integrate import quad

from calibration.css.angular import thesis_fov_response
from calibration.css.detectors import BPW_21, EPD_365, TABLE_C1_ANGLE_DEG, TABLE_C1_EPD_SUN_A
from calibration.css.radiation import (
    STEFAN_BOLTZMANN,
    SUN_TEMPERATURE_CH2_K,
    SUN_TEMPERATURE_K,
    albedo_photocurrent_a,
    albedo_spectral_irradiance,
    band_fraction,
    band_radiance,
    blackbody_exitance,
    earth_angular_radius_deg,
    planck_spectral_exitance,
    planck_spectral_radiance,
    spectral_sum,
    sun_irradiance_from_disc,
    sun_photocurrent_a,
    sun_spectral_irradiance,
    table_c1_scale_constant,
    thermopile_band_radiance,
)

SIGMA_CODATA = 5.670374419e-8  # W m⁻² K⁻⁴ (CODATA 2018)
WIEN_B_CODATA = 2.897771955e-3  # m K


def _integrate_over_wavelength(f, lo=1e-9, hi=1e-1):
    """∫ f(λ) dλ by quadrature in ln λ (independent of the series in band_radiance)."""
    value, _ = quad(lambda u: f(np.exp(u)) * np.exp(u), np.log(lo), np.log(hi), limit=400, epsabs=0, epsrel=1e-11)
    return value


@pytest.mark.parametrize("temperature_k", [3.0, 288.0, 288.15, 5780.0, 5800.0])
def test_integral_of_planck_exitance_is_sigma_t4(temperature_k):
    # quadrature of M_λ against CODATA σT⁴; the brief asks 1e-4 relative, reached ≈ 1e-9
    integral = _integrate_over_wavelength(lambda lam: planck_spectral_exitance(lam, temperature_k),
                                          lo=1e-9 * 300 / temperature_k, hi=1e-1 * 300 / temperature_k)
    assert integral == pytest.approx(SIGMA_CODATA * temperature_k**4, rel=1e-4)
    assert integral == pytest.approx(SIGMA_CODATA * temperature_k**4, rel=1e-8)


def test_sigma_from_constants_and_whole_band_series():
    assert STEFAN_BOLTZMANN == pytest.approx(SIGMA_CODATA, rel=1e-9)
    t = np.array([3.0, 288.0, 5780.0])
    assert np.pi * band_radiance(t) == pytest.approx(SIGMA_CODATA * t**4, rel=1e-9)
    assert blackbody_exitance(t) == pytest.approx(SIGMA_CODATA * t**4, rel=1e-9)


@pytest.mark.parametrize("temperature_k, lo, hi", [
    (288.0, 5.5e-6, 14e-6), (288.0, 5.5e-6, 1e-1), (5780.0, 5.5e-6, 14e-6), (5780.0, 0.2e-6, 1.1e-6),
    (288.0, 40e-6, 60e-6),  # straddles x = hc/(λkT) = 1 (λ ≈ 50 µm), where the series switches branch
    (3.0, 100e-6, 5e-3),
])
def test_band_radiance_against_quadrature(temperature_k, lo, hi):
    expected = _integrate_over_wavelength(lambda lam: planck_spectral_radiance(lam, temperature_k), lo, hi)
    assert band_radiance(temperature_k, lo, hi) == pytest.approx(expected, rel=1e-8)


def test_band_radiance_is_additive_and_the_thermopile_band_uses_its_filter():
    t = 288.0
    whole = band_radiance(t, 5.5e-6, np.inf)
    assert band_radiance(t, 5.5e-6, 50e-6) + band_radiance(t, 50e-6, np.inf) == pytest.approx(whole, rel=1e-12)
    assert thermopile_band_radiance(t) == pytest.approx(0.77 * whole, rel=1e-12)  # > 77 % average transmittance
    assert thermopile_band_radiance(t, transmittance=1.0) == pytest.approx(whole, rel=1e-12)


def test_wien_peaks_match_the_thesis_half_micron_and_ten_micron():
    # ch. 2: solar (and albedo) spectrum peaks near 0.5 µm, Earth's own emission near 10 µm
    for t, expected in [(SUN_TEMPERATURE_K, 0.50e-6), (288.0, 10.0e-6)]:
        lam = np.linspace(0.5, 1.5, 200001) * WIEN_B_CODATA / t
        peak = lam[np.argmax(planck_spectral_radiance(lam, t))]
        assert peak == pytest.approx(WIEN_B_CODATA / t, rel=1e-5)
        assert peak == pytest.approx(expected, rel=0.01)


def test_black_body_sun_spectral_split_is_the_thesis_rough_40_50_10():
    # ch. 2: "≈ 40 % visible, 50 % IR, 10 % UV" (rounded statement); a 5800 K body gives 42 / 46 / 12 %
    uv = band_fraction(SUN_TEMPERATURE_CH2_K, 0.0, 400e-9)
    vis = band_fraction(SUN_TEMPERATURE_CH2_K, 400e-9, 750e-9)
    ir = band_fraction(SUN_TEMPERATURE_CH2_K, 750e-9)
    assert uv + vis + ir == pytest.approx(1.0, abs=1e-12)
    assert (uv, vis, ir) == pytest.approx((0.10, 0.40, 0.50), abs=0.05)


def test_sun_spectrum_integrates_to_the_solar_constant_and_albedo_scales_it():
    total = _integrate_over_wavelength(lambda lam: sun_spectral_irradiance(lam), 1e-8, 1e-3)
    assert total == pytest.approx(1366.0, rel=1e-6)
    lam = np.array([0.3e-6, 0.55e-6, 2e-6])
    assert albedo_spectral_irradiance(lam) == pytest.approx(0.3 * sun_spectral_irradiance(lam), rel=1e-12)
    # the thesis' 5780 K disc of the true 0.533° reproduces the 1366 W m⁻² within 1 %
    assert sun_irradiance_from_disc(5780.0, 0.533) == pytest.approx(1366.0, rel=0.01)


def test_earth_half_angle_65_deg_is_about_660_km():
    # digest §2.2 [A]: the text's 130° Earth (65° half-angle) corresponds to h ≈ 660 km
    assert earth_angular_radius_deg(660e3) == pytest.approx(65.0, abs=0.1)
    assert earth_angular_radius_deg(0.0) == pytest.approx(90.0)


def test_table_c1_scale_constants_of_digest_2_3():
    # digest §2.3: 6.18 µA / 1.2 mm² = 5.15 A m⁻²; 1.17 mA / 7.5 mm² = 156 A m⁻²
    assert table_c1_scale_constant("uv") == pytest.approx(5.15, rel=1e-12)
    assert table_c1_scale_constant("vis") == pytest.approx(156.0, rel=1e-12)
    # albedo: 1.08 µA/(1.2 mm²·0.3) = 3.0 A m⁻²
    assert table_c1_scale_constant("uv", "albedo") == pytest.approx(3.0, rel=1e-12)


def test_eq_3_1_with_the_thesis_angular_response_gives_table_c1_sun_column():
    # S_rel = the pchip FOV curve, K from the 0° entry: every entry agrees within Table C.1's printed
    # 3 significant digits plus the 0° value's own rounding (≤ 0.1 % of 6.18 µA + half a unit in the last digit)
    current = sun_photocurrent_a(thesis_fov_response(TABLE_C1_ANGLE_DEG), EPD_365.active_area_m2, detector="uv")
    assert current[0] == pytest.approx(6.18e-6, rel=1e-12)
    tolerance = 0.0009 * current + 0.5e-2 * 10.0 ** np.floor(np.log10(np.maximum(TABLE_C1_EPD_SUN_A, 1e-30)))
    assert np.all(np.abs(current - TABLE_C1_EPD_SUN_A) <= tolerance)


def test_eq_3_1_and_3_2_from_spectra():
    lam = np.linspace(400e-9, 800e-9, 401)
    e = np.full_like(lam, 1.5e9)  # W m⁻² m⁻¹
    s = np.full_like(lam, 0.34)  # A/W
    k = 1.5e9 * 0.34 * 400e-9  # Σ over n − 1 intervals of a flat spectrum
    assert spectral_sum(lam, e, s) == pytest.approx(k, rel=1e-12)
    i_sun = sun_photocurrent_a(0.5, BPW_21.active_area_m2, wavelength_m=lam, power_density=e, spectral_sensitivity=s)
    assert i_sun == pytest.approx(0.5 * 7.5e-6 * k, rel=1e-12)
    i_alb = albedo_photocurrent_a(0.5, BPW_21.active_area_m2, wavelength_m=lam, power_density=e,
                                  spectral_sensitivity=s)
    assert i_alb == pytest.approx(0.3 * 0.5 * 7.5e-6 * k, rel=1e-12)


def test_photocurrent_inputs_are_checked():
    with pytest.raises(ValueError):
        sun_photocurrent_a(1.0, 1e-6)  # no spectra, no scale, no detector
    with pytest.raises(ValueError):
        sun_photocurrent_a(1.0, 1e-6, wavelength_m=[1e-6, 2e-6], power_density=[1, 1])
    with pytest.raises(ValueError):
        spectral_sum([2e-6, 1e-6], [1, 1], [1, 1])
