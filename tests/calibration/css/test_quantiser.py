"""The 5-bit quantiser of seed 000 (listing D.6, ch. 5.3.4), its inverse (Table C.3) and tables from a response.

Expected numbers are typed from the thesis: the listing's thresholds digit by digit, Table C.1's currents, Table
C.3's codes, and the D.4 script (ported here with numpy and scipy's pchip, MATLAB's interp1 'pchip').
"""

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from calibration.css import quantiser as q

# listing D.6, the thresholds exactly as the `if` chains have them, in the listing's scaled units
LISTING = {
    "epd_albedo": ("kvaepdalb", "e-6", "1.08 1.076 1.068 1.046 1.012 0.9704 0.9232 0.874 0.824 0.779 0.733 0.682 "
                                       "0.627 0.571 0.514 0.459 0.405 0.356 0.311"),
    "epd_sun": ("kvaepdsun", "e-6", "6.18 6.16 6.1 6.0 5.87 5.49 4.76 3.89 3.09 2.29 1.42 0.684 0.309 0.199 0.119 "
                                    "0.064 0.0309 0.00955 0.000112"),
    "bpw_albedo": ("kvabpwalb", "e-4", "2.66 2.66 2.64 2.58 2.5 2.4 2.28 2.16 2.04 1.92 1.81 1.69 1.55 1.41 1.27 "
                                       "1.13 1 0.879 0.77"),
    "bpw_sun": ("kvabpwsun", "e-3", "1.17 1.16 1.15 1.13 1.11 1.04 0.898 0.734 0.583 0.432 0.267 0.129 0.0583 0.0375 "
                                    "0.0224 0.0121 0.00583 0.0018 0.00002"),
    "tps": ("kvatps", "", "13.7843 13.5158 12.7568 10.8241 6.7586 0.1875 -8.6975 -19.8899 -33.5573 -49.3000 "
                          "-66.1502 -83.3928 -100.9151 -118.6173 -136.3827 -154.0849 -171.6072 -188.8498 -205.7000"),
}

# Table C.1: angle, I_EPD,sun, I_EPD,albedo, I_BPW,sun, I_BPW,albedo [A]
C1 = np.array([
    [0, 6.18e-06, 1.08e-06, 1.17e-03, 2.66e-04],
    [5, 6.16e-06, 1.08e-06, 1.16e-03, 2.66e-04],
    [10, 6.10e-06, 1.07e-06, 1.15e-03, 2.64e-04],
    [15, 6.00e-06, 1.05e-06, 1.13e-03, 2.58e-04],
    [20, 5.87e-06, 1.01e-06, 1.11e-03, 2.50e-04],
    [25, 5.49e-06, 9.70e-07, 1.04e-03, 2.40e-04],
    [30, 4.76e-06, 9.23e-07, 8.68e-04, 2.28e-04],
    [35, 3.89e-06, 8.74e-07, 7.34e-04, 2.16e-04],
    [40, 3.09e-06, 8.24e-07, 5.83e-04, 2.04e-04],
    [45, 2.29e-06, 7.79e-07, 4.32e-04, 1.92e-04],
    [50, 1.42e-06, 7.33e-07, 2.67e-04, 1.81e-04],
    [55, 6.84e-07, 6.82e-07, 1.29e-04, 1.69e-04],
    [60, 3.09e-07, 6.27e-07, 5.83e-05, 1.55e-04],
    [65, 1.99e-07, 5.71e-07, 3.75e-05, 1.41e-04],
    [70, 1.19e-07, 5.14e-07, 2.24e-05, 1.27e-04],
    [75, 6.40e-08, 4.59e-07, 1.21e-05, 1.13e-04],
    [80, 3.09e-08, 4.05e-07, 5.83e-06, 1.00e-04],
    [85, 9.55e-09, 3.56e-07, 1.80e-06, 8.79e-05],
    [90, 0.0, 3.11e-07, 0.0, 7.70e-05],
])
COLUMN = {"epd_sun": 1, "epd_albedo": 2, "bpw_sun": 3, "bpw_albedo": 4}

# The code each Table C.1 value gets from the listing's rule, worked by hand. A value at 5k° equal to t_k is not
# above it, so it falls in bin k+1 (the strict `>`): 0° → code 1 (the code-0 edge), …, 90° → 19.
# EPD-albedo: C.1 prints 3 digits where the listing has 4 (1.08 > t1 = 1.076 at 5°, 1.07 > 1.068, 1.05 > 1.046,
# so 5°–15° stay one bin low; 1.01 ≤ 1.012 at 20° skips code 4). BPW-albedo: 2.66 at 0° and 5° is not above
# t0 = t1 = 2.66, so both are code 2 and code 1 is empty. BPW-sun 30°: C.1's 8.68E-04 (typo for 8.98E-04) is
# still ≤ t6 = 0.898 mA and > t7, code 7.
C1_CODES = {
    "epd_sun": [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19],
    "epd_albedo": [1, 1, 2, 3, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19],
    "bpw_sun": [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19],
    "bpw_albedo": [2, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19],
}

# ch. 5.3.4: 00000 direct, +1 per 5°, 10010 = 85–90°, 10011 = 90°
BITS = ["00000", "00001", "00010", "00011", "00100", "00101", "00110", "00111", "01000", "01001", "01010",
        "01011", "01100", "01101", "01110", "01111", "10000", "10001", "10010", "10011"]


def _listing(name):
    function, exponent, digits = LISTING[name]
    return function, exponent, digits.split()


@pytest.mark.parametrize("name", sorted(LISTING))
def test_every_threshold_is_the_listings(name):
    function, exponent, digits = _listing(name)
    table = q.TABLES[name]
    assert table.function == function
    assert len(table.thresholds) == 19 == q.N_THRESHOLDS
    for k, d in enumerate(digits):
        # the same double as the listing's digits times its unit (µA, 10⁻⁴ A, mA, °C)
        assert table.thresholds[k] == float(d + exponent), (name, k, d)
    scale = {"e-6": 1e6, "e-4": 1e4, "e-3": 1e3, "": 1.0}[exponent]
    assert table.listing_scale == scale
    np.testing.assert_allclose(table.listing_thresholds, [float(d) for d in digits], rtol=1e-12)


@pytest.mark.parametrize("name", sorted(C1_CODES))
def test_table_c1_values_get_the_documented_codes(name):
    values = C1[:, COLUMN[name]]
    np.testing.assert_array_equal(q.quantise(values, name), C1_CODES[name])
    bits = getattr(q, q.TABLES[name].function)(values)
    assert list(bits) == [BITS[c] for c in C1_CODES[name]]


def test_the_code_zero_edge_is_strict():
    # x > t0 only: the nominal 0° value itself is code 1, a hair above it is code 0 (digest §5.6 ⚠)
    assert q.quantise(6.18e-6, "epd_sun") == 1
    assert q.quantise(6.1800001e-6, "epd_sun") == 0
    assert q.quantise(1.17e-3, "bpw_sun") == 1 and q.quantise(1.2e-3, "bpw_sun") == 0
    assert q.quantise(13.7843, "tps") == 1 and q.quantise(13.79, "tps") == 0
    assert q.kvatps(15.0) == "00000"
    # the D.4 curve's own 0° value (13.7843) is code 1; Earth seen at 0° per D.2 (13.91 °C) is code 0
    assert q.quantise(13.91, "tps") == 0
    # at and below t18: 19 (10011); the Sun tables' floors make a dark 0 A code 19, not code 18
    assert q.kvaepdsun(0.0) == "10011" and q.kvabpwsun(0.0) == "10011"
    assert q.kvaepdsun(0.000112e-6) == "10011" and q.kvaepdsun(0.000113e-6) == "10010"
    assert q.quantise(-205.7, "tps") == 19 and q.quantise(-205.6, "tps") == 18
    # TvisEarth (−202.4 °C) is inside the 85–90° bin, not at its edge (digest §9 item 15)
    assert q.kvatps(-202.4) == "10010"


def test_the_bpw_albedo_0_to_5_degree_bin_is_empty():
    x = np.linspace(2.5e-4, 2.8e-4, 30001)
    codes = q.quantise(np.append(x, [2.66e-4, np.nextafter(2.66e-4, 1.0)]), "bpw_albedo")
    assert 1 not in codes
    assert set(np.unique(codes)) == {0, 2, 3, 4, 5}  # 2.5e-4 itself is t4: code 5


def test_quantise_is_vectorised_and_checks_its_input():
    x = np.array([[5.9e-6, 5.6e-6], [1.42e-6, 0.0]])
    np.testing.assert_array_equal(q.quantise(x, q.EPD_SUN), [[4, 5], [11, 19]])
    np.testing.assert_array_equal(q.kvaepdsun(x), [["00100", "00101"], ["01011", "10011"]])
    assert q.kvaepdsun(5.9e-6) == "00100" and isinstance(q.kvaepdsun(5.9e-6), str)
    assert q.quantise(0.5, [1.0, 0.0]) == 1  # any non-increasing thresholds
    with pytest.raises(ValueError, match="NaN"):
        q.quantise([1e-6, np.nan], "epd_sun")
    with pytest.raises(ValueError, match="non-increasing"):
        q.quantise(1.0, [0.0, 1.0])
    with pytest.raises(ValueError, match="no quantiser table"):
        q.quantise(1.0, "uv")
    # ch. 6 names the albedo functions kvaepdalbedo/kvabpwalbedo; D.5/D.6 say kvaepdalb/kvabpwalb
    assert q.kvaepdalbedo(1.03e-6) == q.kvaepdalb(1.03e-6) == "00100"
    assert q.kvabpwalbedo(8e-5) == q.kvabpwalb(8e-5) == "10010"


def test_bit_strings_and_back():
    np.testing.assert_array_equal(q.code_bits(np.arange(20)), BITS)
    assert q.code_bits(q.NOT_PROCESSED) == "xxxxx" and q.code_bits(31) == "11111"
    np.testing.assert_array_equal(q.code_from_bits(BITS), np.arange(20))
    assert q.code_from_bits("xxxxx") == q.NOT_PROCESSED == -1
    with pytest.raises(ValueError):
        q.code_from_bits("0012x")
    with pytest.raises(ValueError):
        q.code_bits(32)


def test_the_inverse_angle_of_a_code_is_table_c3():
    # Table C.3 (elevation by the code of face 5/6) and digest §5.7: 90° − bin centre
    c3 = {"10011": 0, "10010": 2.5, "10001": 7.5, "10000": 12.5, "01111": 17.5, "01110": 22.5, "01101": 27.5,
          "01100": 32.5, "01011": 37.5, "01010": 42.5, "01001": 47.5, "01000": 52.5, "00111": 57.5, "00110": 62.5,
          "00101": 67.5, "00100": 72.5, "00011": 77.5, "00010": 82.5, "00001": 87.5, "00000": 90}
    for bits, el in c3.items():
        assert q.elevace(bits) == el and q.azimut(bits) == el
        assert q.code_angle_deg(q.code_from_bits(bits)) == el
    np.testing.assert_array_equal(q.code_incidence_deg([0, 1, 4, 18, 19]), [0, 2.5, 17.5, 87.5, 90])
    assert np.isnan(q.code_incidence_deg(q.NOT_PROCESSED))
    with pytest.raises(ValueError):
        q.code_incidence_deg(20)
    np.testing.assert_array_equal(q.code_incidence_deg([0, 1, 9, 10], step_deg=10), [0, 5, 85, 90])


def test_incidence_code_is_the_bin_an_exact_angle_falls_in():
    np.testing.assert_array_equal(q.incidence_code([0, 4.99, 5, 17, 89.9, 90, 120]), [1, 1, 2, 4, 18, 19, 19])
    # agrees with quantising a strictly decreasing response, here the EPD-sun column between its nodes
    inc = np.linspace(0, 90, 901)
    current = np.interp(inc, C1[:, 0], C1[:, 1])
    np.testing.assert_array_equal(q.quantise(current[:-1], "epd_sun"), q.incidence_code(inc[:-1]))


def test_the_unique_vector_is_six_codes_face_1_first():
    # the D.5 example's EPDsun: faces 2 (00100), 3 (00000), 6 (00101); x → 11111 on board (ch. 6)
    assert q.unique_vector([-1, 4, 0, -1, -1, 5]) == int("11111" "00100" "00000" "11111" "11111" "00101", 2)
    assert q.unique_vector(["xxxxx", "00100", "00000", "xxxxx", "xxxxx", "00101"]) == q.unique_vector(
        [-1, 4, 0, -1, -1, 5])
    with pytest.raises(ValueError):
        q.unique_vector([1, 2, 3])


# ---------------------------------------------------------------------------------------------------------------
# future work (e): tables from a response curve
# ---------------------------------------------------------------------------------------------------------------

def _listing_si(name):
    _, exponent, digits = _listing(name)
    return np.array([float(d + exponent) for d in digits])


def test_thresholds_from_table_c1_reproduce_the_bpw_albedo_table_with_its_empty_bin():
    t = q.thresholds_from_response(C1[:, 0], C1[:, 4])
    np.testing.assert_array_equal(t, _listing_si("bpw_albedo"))
    assert t[0] == t[1] == 2.66e-4  # the empty 0–5° bin comes from C.1 itself


def test_thresholds_from_table_c1_reproduce_the_epd_sun_table_but_its_floor():
    t = q.thresholds_from_response(C1[:, 0], C1[:, 1])
    np.testing.assert_array_equal(t[:18], _listing_si("epd_sun")[:18])
    assert t[18] == 0.0  # C.1's I(90°) = 0; the listing has a 0.112 pA floor
    np.testing.assert_array_equal(q.thresholds_from_response(C1[:, 0], C1[:, 1], floor=0.000112e-6),
                                  _listing_si("epd_sun"))


def test_thresholds_from_table_c1_and_the_bpw_sun_table_differ_at_30_degrees_and_the_floor():
    t = q.thresholds_from_response(C1[:, 0], C1[:, 3], floor=0.00002e-3)
    listing = _listing_si("bpw_sun")
    differ = np.flatnonzero(t != listing)
    np.testing.assert_array_equal(differ, [6])  # 30°: C.1's 8.68E-04 against the listing's 0.898 mA
    assert (t[6], listing[6]) == (8.68e-4, 0.898e-3)


def test_thresholds_from_table_c1_and_the_epd_albedo_table_differ_in_the_digits_c1_rounds():
    t = q.thresholds_from_response(C1[:, 0], C1[:, 2])
    listing = _listing_si("epd_albedo")
    np.testing.assert_array_equal(np.flatnonzero(t != listing), [1, 2, 3, 4, 5, 6])  # 5° … 30°
    # the listing's 4-digit values round to C.1's 3 digits: 1.076 → 1.08, …, 0.9704 → 0.970, 0.9232 → 0.923
    for k in range(1, 7):
        assert float(f"{listing[k]:.2e}") == t[k]


def _d4_curve():
    """seed 000 listing D.4 (digest §6.4): TPS seen temperature H(i), i = 1 … 360, as MATLAB indexes it."""
    angle = [-90, -80, -60, -40, -20, 0, 20, 40, 60, 80, 90]
    sensitivity = [0, 0.005, 0.05, 0.5, 0.95, 1, 0.95, 0.5, 0.05, 0.005, 0]
    tps_sensitivity = PchipInterpolator(angle, sensitivity)(np.arange(-90, 91, 1.0))
    s = np.concatenate([np.zeros(89), tps_sensitivity, np.zeros(90)])
    t = np.full(360, 3.0)
    t[112:248] = 288.0  # T(113:248) = 288
    return np.array([t @ np.roll(s, i) for i in range(1, 361)]) / tps_sensitivity.sum() - 273.0


def test_the_tps_table_is_the_d4_curve_at_i_1_6_to_91():
    h = _d4_curve()
    assert h[89] == pytest.approx(-202.38, abs=0.005)  # H(90): TvisEarth's −202.4 °C (ch. 5.2)
    # the listing read H(1), H(6), …, H(91) as 0°, 5°, …, 90°: the response with H(1) at 0°
    t = q.thresholds_from_response(np.arange(360.0), h)
    np.testing.assert_array_equal(np.round(t, 4), _listing_si("tps"))


def test_thresholds_from_a_response_at_any_step():
    t10 = q.thresholds_from_response(C1[:, 0], C1[:, 1], step_deg=10)
    np.testing.assert_array_equal(t10, C1[::2, 1])
    t25 = q.thresholds_from_response(C1[:, 0], C1[:, 1], step_deg=2.5)
    assert t25.size == 37
    np.testing.assert_allclose(t25[1::2], (C1[:-1, 1] + C1[1:, 1]) / 2, rtol=1e-12)
    assert q.thresholds_from_response(C1[:, 0], C1[:, 1], step_deg=3).size == 31  # the finest that fits 5 bits
    # pchip keeps the nodes, and a finer measured curve works the same
    np.testing.assert_allclose(q.thresholds_from_response(C1[:, 0], C1[:, 1], method="pchip"), C1[:, 1], rtol=1e-12)
    fine = np.linspace(0, 90, 181)
    np.testing.assert_allclose(q.thresholds_from_response(fine, np.cos(np.radians(fine))),
                               np.cos(np.radians(np.arange(0, 91, 5.0))), atol=2e-4)
    # a noisy curve is made non-increasing so that the rule holds
    t = q.thresholds_from_response([0, 5, 10, 90], [1.0, 0.8, 0.85, 0.0], step_deg=5)
    assert np.all(np.diff(t) <= 0) and t[2] == 0.8
    for bad in ({"step_deg": 7}, {"method": "cubic"}):
        with pytest.raises(ValueError):
            q.thresholds_from_response(C1[:, 0], C1[:, 1], **bad)
    with pytest.raises(ValueError, match="cover"):
        q.thresholds_from_response(C1[:10, 0], C1[:10, 1])
    with pytest.raises(ValueError, match="increasing"):
        q.thresholds_from_response(C1[::-1, 0], C1[::-1, 1])
