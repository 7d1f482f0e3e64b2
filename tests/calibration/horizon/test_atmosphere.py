"""The 14–16 µm limb and disc radiance model (seed 004 §2-4-3, App. 2; digest §4.2): Planck band levels, the US
Standard Atmosphere 1976, the limb profile's shape and the CO2 horizon's height."""

import numpy as np
import pytest

from calibration.horizon import atmosphere as A
from calibration.horizon.corrections import effective_horizon_height_km


@pytest.fixture(scope="module")
def tables():
    return {name: A.radiance_table(name, step_km=0.25) for name in A.PROFILE_NAMES}


def test_planck_band_radiance_matches_the_digest_levels():
    """Digest §4.2: 4.1, 6.9 and 11.6 W m⁻² sr⁻¹ over 14–16 µm at 220, 250, 288 K (printed to 2 digits)."""
    assert A.planck_band_radiance([220.0, 250.0, 288.0]) == pytest.approx([4.1, 6.9, 11.6], abs=0.06)
    with pytest.raises(ValueError, match="positive"):
        A.planck_band_radiance(-3.0)


def test_us_standard_1976_temperatures_and_pressures():
    """The layer temperatures (288.15 K at 0, 216.65 K at 11–20 km′, 270.65 K at 47–51 km′, 186.87 K at 86 km,
    195.08 K at 100 km) and the table's pressures at 20, 30, 50, 86 km (5529.3, 1197.0, 79.779, 0.37338 Pa) within
    0.5 % (our hydrostatic integration of the same profile, 0.5 km layers)."""
    t = A.us_standard_1976_temperature_k([0.0, 15.0, 49.0, 88.0, 100.0])
    assert t == pytest.approx([288.15, 216.65, 270.65, 186.87, 195.08], abs=0.02)
    col = A.atmosphere_column(A.profile("us-standard-1976"))
    p = np.interp([20.0, 30.0, 50.0, 86.0], col.altitude_km, col.pressure_pa)
    assert p == pytest.approx([5529.3, 1197.0, 79.779, 0.37338], rel=0.005)


def test_limb_radiance_falls_with_tangent_height_and_stays_in_the_planck_range(tables):
    """Above 25 km every profile's limb radiance falls monotonically to 0 at 100 km (the thesis' cut-off); below, the
    tropical limb brightens from its cold tropopause into the warm stratosphere (15–23 km), as it should. Every
    radiance lies between 0 and the Planck band radiance of the profile's warmest layer; the disc's between those of
    its coldest (times ε) and warmest."""
    z = np.arange(0.0, 100.0, 0.5)
    for name, table in tables.items():
        h = np.arange(25.0, 100.0, 0.25)
        assert np.all(np.diff(table(h)) <= 1e-12), name
        assert table(100.01) == 0.0 and table(300.0) == 0.0
        temps = A.profile(name).temperature(z)
        b_max, b_min = A.planck_band_radiance(temps.max()), A.planck_band_radiance(temps.min())
        assert np.all((table.radiance >= 0) & (table.radiance <= b_max)), name
        disc = table(table.tangent_km[table.tangent_km < 0])
        assert np.all((disc >= A.SURFACE_EMISSIVITY * b_min) & (disc <= b_max)), name
    rises = np.diff(tables["tropical"](np.arange(0.0, 30.0, 0.25))) > 0
    assert rises.any()


def test_the_co2_horizon_sits_near_40_km_and_moves_with_climate(tables):
    """With a point boresight and the pulse normalised near nadir (20° off it), the half-radiance tangent height is
    the classical CO2 horizon seed 004 eq. 2.3 calls H_eq ≈ 40 km: 36–42 km for all six profiles. Through the
    thesis' 2° IFOV the 50 % locator fires much lower (h* 10–27 km): the IFOV averages in the bright disc, and the
    disc-to-limb contrast depends on the climate (tropical lowest)."""
    point = {n: A.half_radiance_height_km(t, float(A.tangent_height_of_angle_km(20.0, 504.652)))
             for n, t in tables.items()}
    assert all(36.0 < v < 42.0 for v in point.values()), point
    blurred = {n: effective_horizon_height_km(t, 504.652) for n, t in tables.items()}
    assert all(10.0 < v < 27.0 for v in blurred.values()), blurred
    assert min(blurred, key=blurred.get) == "tropical"
    assert max(blurred.values()) - min(blurred.values()) > 10.0  # what the per-crossing correction must follow


def test_seasonal_profile_is_hemispherically_alike_in_april_and_rejects_bad_latitudes():
    """12 April (day 103): the summer weight is ≈ 0.47 in both hemispheres, so ±40° give nearly the same profile
    (seed 004 §5-5: the two hemispheres' radiance alike); in January they differ by > 15 K near the surface."""
    north, south = A.seasonal_profile(40.0, 103), A.seasonal_profile(-40.0, 103)
    z = np.arange(0.0, 100.0, 1.0)
    assert np.max(np.abs(north.temperature(z) - south.temperature(z))) < 1.5
    jan_n, jan_s = A.seasonal_profile(40.0, 15), A.seasonal_profile(-40.0, 15)
    assert jan_s.temperature(0.0) - jan_n.temperature(0.0) > 15.0
    with pytest.raises(ValueError, match="latitude"):
        A.seasonal_profile(95.0, 103)
    with pytest.raises(ValueError, match="unknown profile"):
        A.profile("martian")


def test_weather_anomaly_has_the_stated_size_and_height_correlation():
    """400 draws of the ordinary weather: standard deviation 2 K at 5 km, 5 K at 30 km, 8 K at 80 km (±10 %), and
    the correlation between 30 and 36 km near exp(−½) = 0.61 (6 km correlation length)."""
    rng = np.random.default_rng(4)
    z = np.arange(0.0, 100.01, 0.5)
    draws = np.array([A.temperature_anomaly_k(rng, A.ORDINARY_WEATHER, z) for _ in range(400)])
    std = draws.std(axis=0)
    for height, sigma in ((5.0, 2.0), (30.0, 5.0), (80.0, 8.0)):
        assert std[np.searchsorted(z, height)] == pytest.approx(sigma, rel=0.1), height
    r = np.corrcoef(draws[:, np.searchsorted(z, 30.0)], draws[:, np.searchsorted(z, 36.0)])[0, 1]
    assert r == pytest.approx(np.exp(-0.5), abs=0.08)


def test_cold_pool_cools_the_polar_lower_stratosphere_only():
    """The cold pool is −depth from 18 to 30 km, 0 below 12 and above 40 km; a weather profile carries it only
    poleward of 60° (same draw otherwise), and it lowers the thesis' locator's horizon by more than 10 km."""
    assert A.cold_pool_anomaly_k([10.0, 20.0, 29.0, 41.0], 25.0) == pytest.approx([0.0, -25.0, -25.0, 0.0])
    weather = A.WeatherModel(cold_pool_probability=1.0, cold_pool_depth_k=(25.0, 25.0))
    base = A.seasonal_profile(70.0, 103)
    polar = A.weather_profile(base, 70.0, np.random.default_rng(1), weather)
    lower = A.weather_profile(base, 50.0, np.random.default_rng(1), weather)
    assert polar.temperature(24.0) - lower.temperature(24.0) == pytest.approx(-25.0, abs=1e-9)
    assert polar.temperature(5.0) == pytest.approx(lower.temperature(5.0), abs=1e-9)
    h_base = effective_horizon_height_km(A.radiance_table(base, step_km=0.5), 504.652)
    h_pool = effective_horizon_height_km(A.radiance_table(polar, step_km=0.5), 504.652)
    assert h_base - h_pool > 10.0
    with pytest.raises(ValueError, match="probability"):
        A.WeatherModel(cold_pool_probability=1.5)


def test_band_strength_and_the_seven_band_model_move_the_co2_horizon_as_stated(tables):
    """A band 25 % stronger: where the limb is optically thin (70–90 km) its radiance is 1.25× (τ ∝ S), and the
    point-boresight half-radiance height rises (measured 3.9 km for US 1976: more than the thin-limb H ln 1.25 ≈
    1.6 km, as the opaque core's plateau rises too); the 7-sub-band model's half-radiance height is within 1.3 km of
    the default's for all six profiles."""
    ref = float(A.tangent_height_of_angle_km(20.0, 504.652))
    us76 = A.profile("us-standard-1976")
    stronger = A.BandModel(A.CO2_BAND.weights, A.CO2_BAND.unit_depth_heights_km, strength=1.25)
    strong_table = A.radiance_table(us76, stronger, step_km=0.25)
    thin = np.arange(70.0, 90.0, 2.0)
    assert strong_table(thin) / tables["us-standard-1976"](thin) == pytest.approx(1.25, rel=0.03)
    shift = A.half_radiance_height_km(strong_table, ref) - A.half_radiance_height_km(tables["us-standard-1976"], ref)
    assert 1.0 < shift < 6.0, shift
    for name, table in tables.items():
        seven = A.radiance_table(name, A.CO2_BAND_SEVEN, step_km=0.25)
        assert abs(A.half_radiance_height_km(seven, ref) - A.half_radiance_height_km(table, ref)) < 1.3, name
    with pytest.raises(ValueError, match="strength"):
        A.BandModel((1.0,), (30.0,), strength=0.0)
