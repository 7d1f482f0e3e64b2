"""Angular response laws (calibration.css.angular): the thesis' pchip FOV curve against Table C.1, the albedo
S_mean column, and the basic properties of the cosine, power-law and Kelly laws and of the FOV cut-offs."""

import numpy as np
import pytest

from calibration.css.angular import (
    albedo_mean_response,
    cos_incidence,
    cosine_response,
    hard_fov_cutoff,
    incidence_deg,
    kelly_response,
    power_law_response,
    smooth_fov_cutoff,
    thesis_fov_integral,
    thesis_fov_response,
)
from calibration.css.detectors import (
    TABLE_C1_ANGLE_DEG,
    TABLE_C1_BPW_SUN_A,
    TABLE_C1_BPW_SUN_PRINTED_A,
    TABLE_C1_EPD_SUN_A,
)

ANGLES = TABLE_C1_ANGLE_DEG
# Table C.1 / digest §3.5: the "sun/0°" ratio column as the digest prints it (3–4 decimals)
DIGEST_SUN_RATIO = [1.000, 0.997, 0.987, 0.971, 0.950, 0.888, 0.770, 0.629, 0.500, 0.371, 0.230, 0.111, 0.050,
                    0.032, 0.019, 0.0104, 0.0050, 0.0015, 0.0]
# digest §3.5: the "albedo/0°" ratio column (EPD)
DIGEST_ALBEDO_RATIO = [1.000, 1.000, 0.991, 0.972, 0.935, 0.898, 0.855, 0.809, 0.763, 0.721, 0.679, 0.631, 0.581,
                       0.529, 0.476, 0.425, 0.375, 0.330, 0.288]


def _rounding_interval(printed):
    """Ratio interval I/I(0°) allowed by 3-significant-digit rounding of the printed currents."""
    printed = np.asarray(printed, float)
    half = np.where(printed > 0, 0.5e-2 * 10.0 ** np.floor(np.log10(np.where(printed > 0, printed, 1.0))), 0.0)
    return (printed - half) / (printed[0] + half[0]), (printed + half) / (printed[0] - half[0])


def test_fov_curve_knots_symmetry_and_zero_beyond_90():
    knots = [0, 20, 40, 60, 80, 90]
    assert thesis_fov_response(knots) == pytest.approx([1, 0.95, 0.5, 0.05, 0.005, 0], abs=1e-15)
    a = np.linspace(0, 90, 181)
    assert thesis_fov_response(-a) == pytest.approx(thesis_fov_response(a), abs=1e-15)
    assert np.all(thesis_fov_response([90, 90.1, 120, 180]) == 0.0)
    assert np.all(np.diff(thesis_fov_response(a)) <= 0)


def test_fov_curve_is_table_c1_sun_ratio_to_the_digest_decimals():
    # digest §3.5 finding 1: "equals, to 3–4 decimals"; worst |Δ| reached 8e-4 (EPD, 10° and 50°)
    fov = thesis_fov_response(ANGLES)
    assert np.max(np.abs(fov - TABLE_C1_EPD_SUN_A / TABLE_C1_EPD_SUN_A[0])) <= 1e-3
    # against the digest's own rounded column: 1e-3 plus half a unit of its 3rd decimal (reached 1.02e-3 at 50°)
    assert np.max(np.abs(fov - np.array(DIGEST_SUN_RATIO))) <= 1.5e-3
    # the two points the digest quotes to 4 decimals: 25° → 0.8881, 55° → 0.1107
    assert thesis_fov_response([25.0, 55.0]) == pytest.approx([0.8881, 0.1107], abs=5e-5)


@pytest.mark.parametrize("column", [TABLE_C1_EPD_SUN_A, TABLE_C1_BPW_SUN_A], ids=["epd", "bpw_corrected"])
def test_fov_curve_lies_within_table_c1_rounding_for_both_photodiodes(column):
    lo, hi = _rounding_interval(column)
    fov = thesis_fov_response(ANGLES)
    assert np.all((fov >= lo - 1e-12) & (fov <= hi + 1e-12))


def test_printed_bpw_sun_30_deg_is_inconsistent_with_the_curve():
    # digest §9.7: 8.68E-04 lies outside the rounding interval at 30°; 8.98E-04 lies inside
    lo, hi = _rounding_interval(TABLE_C1_BPW_SUN_PRINTED_A)
    i30 = int(np.flatnonzero(ANGLES == 30.0)[0])
    assert not lo[i30] <= thesis_fov_response(30.0) <= hi[i30]


def test_fov_integral_is_exact_and_additive():
    a = np.linspace(-90, 90, 180001)
    trapezoid = np.sum((thesis_fov_response(a[1:]) + thesis_fov_response(a[:-1])) / 2 * np.diff(a))
    assert thesis_fov_integral(-90.0, 90.0) == pytest.approx(trapezoid, rel=1e-8)
    assert thesis_fov_integral(-90, 10) + thesis_fov_integral(10, 90) == pytest.approx(thesis_fov_integral(-90, 90))
    assert thesis_fov_integral(-200, 200) == pytest.approx(thesis_fov_integral(-90, 90))
    assert thesis_fov_integral(5, 5) == 0.0


def test_albedo_mean_response_is_table_c1_albedo_column():
    uv = albedo_mean_response(ANGLES, "uv")
    assert np.max(np.abs(uv - np.array(DIGEST_ALBEDO_RATIO))) <= 5e-4
    vis = albedo_mean_response(ANGLES, "vis")
    assert np.max(np.abs(vis / uv - 1.0)) <= 0.007  # digest: "the same to within about 0.5 %"; reached 0.61 %
    fine = albedo_mean_response(np.linspace(0, 90, 901))
    assert np.all(np.diff(fine) <= 1e-15)
    assert np.isnan(albedo_mean_response(95.0))
    assert albedo_mean_response(-40.0) == pytest.approx(albedo_mean_response(40.0))


@pytest.mark.parametrize("law", [
    cosine_response,
    lambda a: power_law_response(a, 1.7),
    lambda a: power_law_response(a, 0.6),
    lambda a: kelly_response(cos_incidence(a), 0.1, normalize=True),
    thesis_fov_response,
], ids=["cosine", "power1.7", "power0.6", "kelly", "thesis"])
def test_laws_are_one_at_normal_zero_beyond_90_and_monotone(law):
    assert law(0.0) == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.asarray(law([90.0, 90.5, 100.0, 135.0, 180.0])) == pytest.approx(0.0, abs=1e-15))
    a = np.linspace(0.0, 90.0, 901)
    values = np.asarray(law(a))
    assert np.all(np.diff(values) <= 1e-15)
    assert np.all(values[1:-1] < 1.0) and np.all(values[:-1] > 0.0)
    assert law(-30.0) == pytest.approx(law(30.0))


def test_cosine_and_power_law_values():
    assert cosine_response(60.0) == pytest.approx(0.5)
    assert power_law_response(60.0, 2.0) == pytest.approx(0.25)
    assert power_law_response([10.0, 50.0], 1.0) == pytest.approx(cosine_response([10.0, 50.0]))
    with pytest.raises(ValueError):
        power_law_response(10.0, 0.0)


def test_kelly_is_basilisk_form():
    # Basilisk CoarseSunSensor: KellyFit = 1 − exp(−γ²/κ), signal = γ·KellyFit
    assert kelly_response(0.5, 0.1) == pytest.approx(0.5 * (1.0 - np.exp(-2.5)), rel=1e-14)
    assert kelly_response(1.0, 0.1) == pytest.approx(1.0 - np.exp(-10.0), rel=1e-14)
    assert kelly_response(1.0, 0.5, normalize=True) == pytest.approx(1.0, rel=1e-14)
    assert kelly_response(-0.3, 0.1) == 0.0
    # κ → 0 gives the cosine where γ ≫ √κ; the Kelly curve lies below the cosine everywhere
    g = np.linspace(0.2, 1.0, 9)
    assert kelly_response(g, 1e-4) == pytest.approx(g, rel=1e-12)
    g = np.linspace(0.01, 1.0, 100)
    assert np.all(kelly_response(g, 0.1) < g)
    with pytest.raises(ValueError):
        kelly_response(0.5, 0.0)


def test_angle_cos_round_trip():
    a = np.array([0.0, 12.5, 45.0, 89.0, 120.0])
    assert incidence_deg(cos_incidence(a)) == pytest.approx(a, abs=1e-9)


def test_hard_and_smooth_fov_cutoffs():
    assert hard_fov_cutoff([0, 59.9, 60, 60.1, -70], 60.0) == pytest.approx([1, 1, 1, 0, 0])
    h, w = 60.0, 10.0
    assert smooth_fov_cutoff([0.0, 55.0, 60.0, 65.0, 80.0, -60.0], h, w) == pytest.approx([1, 1, 0.5, 0, 0, 0.5])
    a = np.linspace(40, 80, 4001)
    s = smooth_fov_cutoff(a, h, w)
    assert np.all(np.diff(s) <= 0)
    slope = np.diff(s) / np.diff(a)
    assert np.max(np.abs(np.diff(slope))) < 1e-3  # continuous first derivative (no kink at the band edges)
    assert np.min(slope) == pytest.approx(-np.pi / (2 * w), rel=1e-3)
    assert smooth_fov_cutoff([59.0, 60.0, 61.0], h, 0.0) == pytest.approx(hard_fov_cutoff([59.0, 60.0, 61.0], h))
    with pytest.raises(ValueError):
        smooth_fov_cutoff(10.0, h, -1.0)
