"""The TPS 230's seen temperature (calibration.css.thermopile): listings D.2–D.4 of seed 000, §5.2's numbers,
Fig. 5.2 (the digest's table of it) and the kvatps thresholds of listing D.6, plus the general model."""

import numpy as np
import pytest

from calibration.css.angular import thesis_fov_response
from calibration.css.radiation import thermopile_band_radiance
from calibration.css.thermopile import (
    T_VIS_EARTH_C,
    band_brightness_temperature_k,
    d2_earth_seen_temperature_c,
    d3_sun_seen_temperature_c,
    d4_seen_temperature_curve_c,
    fig52_seen_temperature_c,
    seen_brightness_temperature_k,
    seen_temperature_k,
    sun_seen_temperature_k,
    weighted_seen_temperature,
)

# digest §5.2 [R]: the Fig. 5.2 curve H(i) of listing D.4 (the figure itself is lost; not printed by the thesis)
FIG52_I = [0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80, 85, 90, 95, 100, 120]
FIG52_H = [13.784, 13.606, 12.964, 11.358, 7.769, 1.700, -6.749, -17.451, -30.636, -46.025, -62.743, -79.919,
           -97.393, -115.068, -132.831, -150.555, -168.122, -185.428, -202.380, -218.437, -232.570, -265.215]
# listing D.6, function kvatps: the TPS quantiser thresholds as printed (4 decimals)
KVATPS = [13.7843, 13.5158, 12.7568, 10.8241, 6.7586, 0.1875, -8.6975, -19.8899, -33.5573, -49.3000, -66.1502,
          -83.3928, -100.9151, -118.6173, -136.3827, -154.0849, -171.6072, -188.8498, -205.7000]


def test_earth_seen_at_zero_deg_listing_d2():
    t = d2_earth_seen_temperature_c()
    assert round(t, 2) == 13.91  # §5.2 (reached 13.91179)
    assert t == pytest.approx(13.9118, abs=5e-5)  # digest [R]


def test_sun_seen_at_zero_deg_listing_d3():
    t = d3_sun_seen_temperature_c()
    assert round(t, 2) == -234.13  # §5.2 (reached −234.12849)
    assert t == pytest.approx(-234.1285, abs=5e-5)  # digest [R]


def test_earth_seen_at_90_deg_listing_d4():
    h = d4_seen_temperature_curve_c()
    assert h.shape == (360,)
    assert round(float(h[90]), 1) == -202.4  # §5.2 and D.5's TvisEarth (reached −202.3799)
    assert round(float(h[90]), 2) == -202.38  # digest [R]
    assert round(float(h[90]), 1) == T_VIS_EARTH_C


def test_fig52_table_of_the_digest():
    # to 1e-3 °C (the digest prints 3 decimals; worst reached 4.5e-4)
    assert fig52_seen_temperature_c(FIG52_I) == pytest.approx(FIG52_H, abs=1e-3)
    assert fig52_seen_temperature_c(360) == fig52_seen_temperature_c(0)
    # ≥ 150°: ≈ −270 °C (space only, apart from the 136° Earth's far edge)
    assert np.all(np.abs(fig52_seen_temperature_c(np.arange(150, 211)) + 270.0) < 0.5)


def test_kvatps_thresholds_are_fig52_at_one_past_each_5_deg_step():
    # listing D.6: t_k = H(5k + 1), k = 0 … 18 (digest §5.6): H rounded to the listing's 4 decimals is the printed
    # threshold, every one of the 19 (worst |Δ| before rounding 4.96e-5)
    h = fig52_seen_temperature_c(np.arange(1, 92, 5))
    assert np.round(h, 4) == pytest.approx(KVATPS, abs=1e-9)


def test_sun_and_earth_separate():
    # §5.2: the Sun's highest seen temperature lies below the Earth's lowest (the 90° edge)
    assert d3_sun_seen_temperature_c() < d4_seen_temperature_curve_c()[90]
    assert d2_earth_seen_temperature_c() > d4_seen_temperature_curve_c()[0]  # D.2 uses 288.15 K/−273.15


def test_general_model_follows_listing_d4():
    # a 68° Earth half-angle at off-nadir i − 0.5° is D.4's ring; exact pchip integrals against the listing's 1°
    # sampling agree to 0.01 °C (reached 0.004 °C) over 0 … 120°
    i = np.arange(0, 121)
    continuous = seen_temperature_k(68.0, i - 0.5, 288.0, 3.0) - 273.0
    assert np.max(np.abs(continuous - d4_seen_temperature_curve_c()[i])) < 0.01


def test_general_model_properties():
    a = np.linspace(0.0, 180.0, 361)
    t = seen_temperature_k(65.0, a)
    assert seen_temperature_k(65.0, -a) == pytest.approx(t)
    assert np.all(np.diff(t) <= 1e-12)
    assert seen_temperature_k(180.0, 0.0) == pytest.approx(288.15)  # Earth fills the half space
    assert seen_temperature_k(65.0, 155.0) == pytest.approx(3.0)  # Earth wholly behind the face
    # the same weights by the numeric path (any response callable) as by the exact one
    numeric = seen_temperature_k(65.0, [0.0, 30.0, 90.0], response=thesis_fov_response, step_deg=0.005)
    assert numeric == pytest.approx(seen_temperature_k(65.0, [0.0, 30.0, 90.0]), abs=2e-3)


def test_sun_model_follows_listing_d3():
    # the Sun as a 0.5° disc on axis; continuous integral against D.3's 0.5° samples, to 0.01 °C
    assert float(sun_seen_temperature_k(0.0)) - 273.15 == pytest.approx(-234.13, abs=0.01)
    assert sun_seen_temperature_k(95.0) == pytest.approx(3.0)


def test_weighted_average_is_eq_3_3_as_the_listings_use_it():
    assert weighted_seen_temperature([1.0, 3.0], [300.0, 100.0]) == pytest.approx(150.0)


def test_brightness_temperature_inverts_band_radiance():
    t = np.array([30.0, 250.0, 288.15, 5780.0])
    assert band_brightness_temperature_k(thermopile_band_radiance(t)) == pytest.approx(t, rel=1e-9)
    assert seen_brightness_temperature_k(180.0, 0.0) == pytest.approx(288.15, rel=1e-9)
    assert band_brightness_temperature_k(0.0) == 0.0  # space (3 K) has no radiance above 5.5 µm


def test_radiance_average_reads_the_sun_far_hotter_than_the_thesis_model():
    # band radiance ∝ ≈ T⁵ and faster above 5.5 µm, so a 0.5° Sun dominates the average; the thesis' linear
    # temperature average gives −234 °C, the radiometric one is above the Earth's 288 K
    sun = float(seen_brightness_temperature_k(0.0, 0.0, sun_off_axis_deg=0.0))
    assert sun > 288.15
    earth = float(seen_brightness_temperature_k(65.0, 0.0))
    assert float(seen_temperature_k(65.0, 0.0)) < earth < 288.15
