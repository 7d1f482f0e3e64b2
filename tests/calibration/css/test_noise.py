"""Seed 000's noise chain (§4.1, listings D.1, Table C.2) and the physical variant (calibration.css.noise).

Every expected number is typed in from the thesis (or the digest where marked [R]/[A] — recomputed or added by
the digest's author, not printed by the thesis), at its printed precision.
"""

import numpy as np
import pytest

from calibration.css.detectors import (
    BPW_21,
    EPD_365,
    FRONT_END_BPW,
    FRONT_END_EPD,
    FRONT_END_TPS,
    TPS_230,
    non_inverting_gain,
    table_c1_current_a,
)
from calibration.css.noise import (
    TABLE_C2_COLUMNS,
    physical_photodiode_noise,
    physical_thermopile_noise,
    thermopile_temperature_noise_k,
    thesis_bpw_noise_v,
    thesis_epd_noise_nep_v,
    thesis_epd_noise_two_impedance_v,
    thesis_snr_db,
    thesis_snr_table,
    thesis_tps_noise_v,
    thesis_tps_source_resistance,
    two_impedance_thermal_noise_v2,
)

# Table C.2 as printed (seed 000 appendix C.2), rows 0 … 85° in 5° steps, columns as TABLE_C2_COLUMNS
TABLE_C2 = np.array([
    [75.20, 75.69, 90.35, 90.85, 104.20, 117.07],
    [75.20, 75.69, 90.33, 90.82, 104.20, 116.99],
    [75.12, 75.61, 90.24, 90.73, 104.14, 116.92],
    [74.96, 75.45, 90.10, 90.59, 103.94, 116.77],
    [74.62, 75.11, 89.90, 90.40, 103.66, 116.62],
    [74.27, 74.76, 89.32, 89.82, 103.31, 116.05],
    [73.83, 74.33, 88.09, 88.58, 102.87, 114.78],
    [73.36, 73.86, 86.33, 86.83, 102.40, 113.02],
    [72.85, 73.34, 84.33, 84.83, 101.90, 111.02],
    [72.36, 72.86, 81.73, 82.22, 101.38, 108.42],
    [71.84, 72.33, 77.58, 78.07, 100.86, 104.24],
    [71.20, 71.70, 71.23, 71.73, 100.27, 97.92],
    [70.48, 70.97, 64.33, 64.83, 99.52, 91.02],
    [69.67, 70.16, 60.51, 61.00, 98.69, 87.19],
    [68.75, 69.24, 56.04, 56.54, 97.79, 82.71],
    [67.77, 68.26, 50.66, 51.15, 96.77, 77.37],
    [66.68, 67.18, 44.33, 44.83, 95.70, 71.02],
    [65.56, 66.06, 34.13, 34.63, 94.59, 60.82],
])


def test_gain_and_bandwidth_of_section_4_1():
    # eq. 4.1/4.2: G = 4.3 and BW = 83,721 Hz (EPD, BPW); BW = 892.3282 Hz (TPS, R1 = 820 Ω)
    assert FRONT_END_EPD.gain == pytest.approx(4.3, rel=1e-15)
    assert round(FRONT_END_EPD.bandwidth_hz, 2) == 83720.93  # digest §8.6; the text rounds to 83721
    assert round(FRONT_END_BPW.bandwidth_hz) == 83721
    assert round(FRONT_END_TPS.bandwidth_hz, 4) == 892.3282  # as printed in §4.1 (reached to 1e-4 Hz)
    assert round(FRONT_END_TPS.bandwidth_hz, 2) == 892.33
    assert round(float(non_inverting_gain(820.0, 330e3)), 2) == 403.44  # digest [R]


def test_bpw_worked_example_eqs_4_6_to_4_10():
    un = thesis_bpw_noise_v()
    assert round(un * 1e6, 2) == 7.21  # eq. 4.8: 7.21 µV (reached 7.2105 µV)
    u_sig = 0.266e-3 * FRONT_END_BPW.r_in_ohm
    assert u_sig == pytest.approx(0.5852, abs=1e-12)  # eq. 4.9
    assert round(float(thesis_snr_db(u_sig, un)), 1) == 104.2  # eq. 4.10
    assert round(float(thesis_snr_db(0.5852, 7.21e-6)), 1) == 104.2  # the thesis' own arithmetic


def test_epd_noise_voltages_of_section_4_1():
    # manual results: NEP method 35.459 µV, two-impedance method 37.529 µV (reached 35.4589 / 37.5286 µV)
    assert round(thesis_epd_noise_nep_v() * 1e6, 3) == 35.459
    assert round(thesis_epd_noise_two_impedance_v() * 1e6, 3) == 37.529


def test_tps_noise_voltages_of_listings_d17_d18():
    r_0 = thesis_tps_source_resistance(15.0)
    r_35 = thesis_tps_source_resistance(-20.0)
    assert r_0 == 163900.0 and r_35 == 968201.0  # R1 lines of listings D.1.7 and D.1.8 (Table 6 R_max1)
    un_0, un_35 = thesis_tps_noise_v([r_0, r_35])
    assert round(un_0 * 1e6, 1) == 8.3  # §4.1: 8.3 µV (reached 8.299 µV)
    assert round(un_35 * 1e6) == 48  # §4.1: 48 µV (reached 48.43 µV)
    # [R] NOT printed by the thesis: the digest's SNRs of D.1.7/D.1.8 with their U_s = 0.24 mV and 0.94 mV
    assert round(float(thesis_snr_db(0.24e-3, un_0)), 1) == 35.2
    assert round(float(thesis_snr_db(0.94e-3, un_35)), 1) == 31.8


def test_listing_signal_voltages_come_from_datasheet_table_4():
    # U_s = 0.94 mV is Table 4 at −20 °C; 0.24 mV is Table 4 read at 15 °C (the curve gives 0.248 mV)
    assert TPS_230.output_voltage(-20.0) == pytest.approx(-0.94e-3, abs=1e-15)
    assert abs(TPS_230.output_voltage(15.0) - (-0.24e-3)) < 0.01e-3


@pytest.mark.parametrize("column", TABLE_C2_COLUMNS)
def test_every_entry_of_table_c2(column):
    # all 18 rows to ±0.01 dB (worst reached: 0.0098 dB, BPW albedo at 80°); BPW Sun at 30° with 0.898 mA
    j = TABLE_C2_COLUMNS.index(column)
    computed = thesis_snr_table()[column]
    assert computed.shape == (18,)
    assert np.max(np.abs(computed - TABLE_C2[:, j])) <= 0.01


def test_bpw_sun_30_deg_printed_current_does_not_give_table_c2():
    table = thesis_snr_table(bpw_sun_a=table_c1_current_a("vis", "sun", printed=True))
    assert round(float(table["bpw_sun"][6]), 2) == 114.48  # digest §3.5: 8.68E-04 gives 114.48 dB
    assert abs(table["bpw_sun"][6] - 114.78) > 0.2


def test_two_impedance_formula_reduces_to_johnson_noise():
    k, t, b = 1.380649e-23, 300.0, 1e4
    # R_sh → ∞: 4kTBR_in; equal temperatures: 4kTB(R_sh ∥ R_in)
    assert two_impedance_thermal_noise_v2(b, 1e30, t, 1e5, t) == pytest.approx(4 * k * t * b * 1e5, rel=1e-12)
    assert two_impedance_thermal_noise_v2(b, 3e5, t, 1e5, t) == pytest.approx(4 * k * t * b * 7.5e4, rel=1e-12)


def test_physical_shot_noise_of_digest_4_4():
    # digest §4.4 [A] (not in the thesis): shot noise over B = 83.7 kHz — BPW-sun 0°: 5.6 nA → 12.3 µV
    # across 2.2 kΩ; EPD-sun 0°: 0.41 nA → 40.7 µV across 100 kΩ
    bpw = physical_photodiode_noise(1.17e-3, BPW_21, FRONT_END_BPW, noise_bandwidth_factor=1.0)
    epd = physical_photodiode_noise(6.18e-6, EPD_365, FRONT_END_EPD, noise_bandwidth_factor=1.0)
    assert round(float(bpw.shot_v) * 1e6, 1) == 12.3
    assert round(float(epd.shot_v) * 1e6, 1) == 40.7
    # ... larger than the thesis' total, which leaves shot noise out
    assert bpw.total_v > thesis_bpw_noise_v()
    assert epd.total_v > thesis_epd_noise_two_impedance_v()


def test_physical_noise_terms_and_averaging():
    b = 83720.93023255814
    budget = physical_photodiode_noise([0.0, 2.66e-4], BPW_21, FRONT_END_BPW, noise_bandwidth_factor=1.0,
                                       surface_temperature_c=25.0, inside_temperature_c=25.0)
    # NEP converted to a voltage: NEP·√B·R_λ·R_in
    assert budget.nep_v == pytest.approx(7.2e-14 * np.sqrt(b) * 0.34 * 2200, rel=1e-9)
    # Johnson noise of ≈ 2.2 kΩ (R_sh ≫ R_in) at 298.15 K
    assert budget.johnson_v[0] == pytest.approx(np.sqrt(4 * 1.380649e-23 * 298.15 * b * 2200), rel=1e-5)
    assert budget.amplifier_voltage_v[0] == pytest.approx(18e-9 * np.sqrt(b), rel=1e-12)
    assert budget.shot_v[0] == 0.0 and budget.shot_v[1] > 0.0
    assert budget.sigma_v == pytest.approx(budget.total_v / 4.0, rel=1e-12)  # 16 samples → ÷√16
    assert budget.sigma_a == pytest.approx(budget.sigma_v / 2200.0, rel=1e-12)
    # π/2 noise bandwidth by default: every term scales by √(π/2)
    default = physical_photodiode_noise([0.0, 2.66e-4], BPW_21, FRONT_END_BPW)
    assert default.total_v == pytest.approx(budget.total_v * np.sqrt(np.pi / 2), rel=1e-12)


def test_physical_snr_stays_above_80_db_at_normal_incidence():
    # digest §4.4 [A]: with shot noise "SNRs would fall by a few dB but stay above 80 dB at 0°"
    for detector, front_end, current in [(BPW_21, FRONT_END_BPW, 1.17e-3), (EPD_365, FRONT_END_EPD, 6.18e-6)]:
        budget = physical_photodiode_noise(current, detector, front_end)
        assert budget.snr_db > 80.0


def test_physical_thermopile_noise_and_temperature_equivalent():
    budget = physical_thermopile_noise(0.24e-3, noise_bandwidth_factor=1.0, n_average=1)
    b = 892.328154283296
    assert budget.total_v == pytest.approx(np.sqrt((40e-9**2 + 18e-9**2) * b), rel=1e-9)
    assert np.isnan(budget.sigma_a)
    # §4.4 says 8.3 µV ≈ 1 °C; the Table 4 slope near 15 °C makes it ≈ 0.36 K (digest §9.11 [A])
    sigma_t = float(thermopile_temperature_noise_k(8.3e-6, 15.0))
    assert 0.3 < sigma_t < 0.4
