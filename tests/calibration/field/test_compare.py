"""A sensor's field run against the Sun (calibration.field.compare), on truth from the field simulator.

The field day is seed 003 §5's: 29 Sep 2019, 10:58–16:25 local (UTC+7, 03:58–09:25 UTC), a roof in Novosibirsk
(54.84 N, 83.09 E, 160 m), the sensor pointing up with a 60° half field of view, clear until about 12:00 local
and clouds after. One sample per 30 s. Noise: σ = 0.1° per component in the sensor frame, so the zenith and
horizontal-arc errors have RMS ≈ 0.1° and the vector error ≈ 0.1°·√2.
"""

import numpy as np
import pytest
from field_simulation import atmosphere_of, readings, site_of

from calibration.errors import FieldDataError
from calibration.field.compare import compare_with_sun
from calibration.field.sky import Mount, Site, utc_seconds
from drivers.sim.sky import CloudBank, SimulatedMount, SimulatedSky

START = float(utc_seconds("2019-09-29T03:58:17")[0])
END = float(utc_seconds("2019-09-29T09:24:45")[0])
NOON_LOCAL = float(utc_seconds("2019-09-29T05:00:00")[0])
TIMES = np.arange(START, END, 30.0)
CLOUDS = (CloudBank(start_s=NOON_LOCAL + 1800, duration_s=3600.0, speed_deg_s=0.003, direction_deg=40.0),
          CloudBank(start_s=NOON_LOCAL + 6600, duration_s=900.0, speed_deg_s=0.002, direction_deg=200.0,
                    transmission=0.2))
CLEAR_SKY = SimulatedSky(54.84, 83.09, 160.0, pressure_hpa=995.0, temperature_c=8.0, delta_t_s=69.0)
CLOUDY_SKY = SimulatedSky(54.84, 83.09, 160.0, pressure_hpa=995.0, temperature_c=8.0, delta_t_s=69.0, clouds=CLOUDS)
SITE, ATM = site_of(CLEAR_SKY), atmosphere_of(CLEAR_SKY)
HEADING = 17.3
MOUNT = SimulatedMount(HEADING, 0.0, 0.0)
SIGMA = 0.1


@pytest.fixture(scope="module")
def clear_day():
    th, ph = readings(CLEAR_SKY, MOUNT, TIMES, SIGMA, np.random.default_rng(30))
    return th, ph


def test_clear_day_statistics_are_the_simulated_noise(clear_day):
    th, ph = clear_day
    c = compare_with_sun(TIMES, th, ph, SITE, Mount(HEADING), ATM, fov_half_deg=60.0)
    s = c.summary
    print(f"\nclear day, 0.1° per component: {s.count} samples in the FOV; zenith RMS {s.zenith.rms:.4f}°, "
          f"azimuth RMS {s.azimuth.rms:.4f}° (arc {s.azimuth_arc.rms:.4f}°), vector RMS {s.vector.rms:.4f}° "
          f"(std {s.vector.std:.4f}°, mean {s.vector.mean:.4f}°, max {s.vector.max_abs:.4f}°)")
    assert s.count == int(c.used.sum()) == int(c.in_fov.sum()) > 100
    assert s.zenith.rms == pytest.approx(SIGMA, rel=0.15)
    assert s.azimuth_arc.rms == pytest.approx(SIGMA, rel=0.15)
    assert s.vector.rms == pytest.approx(SIGMA * np.sqrt(2), rel=0.15)
    assert abs(s.zenith.mean) < 4 * SIGMA / np.sqrt(s.count)  # no bias: the SPA and the simulator agree
    # the Sun leaves the 60° field of view in the morning and afternoon: flagged, left out, said in words
    assert not c.in_fov.all() and (c.sun_sensor_zenith_deg[~c.in_fov] > 60.0).all()
    assert any("outside the 60° half field of view" in w for w in c.warnings)
    assert c.mount_fit is None and any("absolute" in n for n in c.notes)
    # the sky zenith error is the sensor's θ error for a level sensor
    assert np.allclose(c.zenith_error_deg, c.sensor_zenith_error_deg, atol=1e-9)


def test_unknown_heading_is_fitted_and_the_azimuth_becomes_relative(clear_day):
    th, ph = clear_day
    c = compare_with_sun(TIMES, th, ph, SITE, Mount(0.0), ATM, heading="fit")
    fit = c.mount_fit
    print(f"\nheading fitted: {fit.heading_deg:.4f}° ± {fit.heading_sigma_deg:.4f}° (true {HEADING}°) over "
          f"{fit.n_samples} samples; azimuth mean {c.summary.azimuth.mean:+.5f}°, RMS {c.summary.azimuth.rms:.4f}°")
    assert abs(fit.heading_deg - HEADING) < 3 * fit.heading_sigma_deg
    assert fit.heading_sigma_deg < 0.05
    assert c.mount.heading_deg == fit.heading_deg
    assert any("relative, not absolute" in n for n in c.notes)
    assert abs(c.summary.azimuth.mean) < 0.01
    # the same data compared with a wrong heading, not fitted: a large azimuth error and a warning
    wrong = compare_with_sun(TIMES, th, ph, SITE, Mount(HEADING - 5.0), ATM)
    assert wrong.summary.azimuth.mean == pytest.approx(-5.0, abs=0.05)
    assert any("large scatter" in w for w in wrong.warnings)


def test_level_fit_recovers_a_tilt_and_says_the_zenith_is_relative():
    tilted = SimulatedMount(HEADING, 0.5, -0.3)
    th, ph = readings(CLEAR_SKY, tilted, TIMES, SIGMA, np.random.default_rng(31))
    level = compare_with_sun(TIMES, th, ph, SITE, Mount(HEADING), ATM)
    fitted = compare_with_sun(TIMES, th, ph, SITE, Mount(0.0), ATM, heading="fit", level="fit")
    f = fitted.mount_fit
    print(f"\nlevel fitted: heading {f.heading_deg:.3f} ± {f.sigma_deg['heading']:.3f}°, roll {f.roll_deg:.3f} ± "
          f"{f.sigma_deg['roll']:.3f}°, pitch {f.pitch_deg:.3f} ± {f.sigma_deg['pitch']:.3f}°; zenith RMS "
          f"{level.summary.zenith.rms:.3f}° (level assumed) → {fitted.summary.zenith.rms:.3f}° (fitted)")
    for name, truth in (("heading", HEADING), ("roll", 0.5), ("pitch", -0.3)):
        assert abs(getattr(f, name + "_deg") - truth) < 4 * f.sigma_deg[name]
    assert fitted.summary.zenith.rms < level.summary.zenith.rms
    assert any("zenith errors are relative" in n for n in fitted.notes)


def test_cloudy_samples_are_flagged_out_of_the_clear_statistics():
    rng = np.random.default_rng(32)
    th, ph = readings(CLOUDY_SKY, MOUNT, TIMES, SIGMA, rng)
    states = [CLOUDY_SKY.cloud_state(t) for t in TIMES]
    cloudy = np.array([not s.clear for s in states])
    covered = np.array([s.covered_fraction() for s in states])
    # a partly covered disc shifts the centroid away from the cloud (up to a disc radius); a fully covered one
    # gives no spot at all
    invalid = covered > 0.999
    th = th + np.where(cloudy & ~invalid, 0.27 * covered + 0.2, 0.0)
    th[invalid] = np.nan
    assert cloudy.sum() > 50 and invalid.sum() > 10
    c = compare_with_sun(TIMES, th, ph, SITE, Mount(HEADING), ATM, cloudy=cloudy)
    clear_only = compare_with_sun(TIMES[~cloudy], th[~cloudy], ph[~cloudy], SITE, Mount(HEADING), ATM)
    print(f"\ncloudy day: {int(cloudy.sum())} cloud-flagged samples ({int(invalid.sum())} without a spot); clear "
          f"zenith RMS {c.summary.zenith.rms:.4f}° over {c.summary.count}; cloudy-and-in-FOV zenith RMS "
          f"{np.sqrt(np.nanmean(c.zenith_error_deg[cloudy & c.in_fov & c.valid] ** 2)):.3f}°")
    assert c.summary == clear_only.summary
    assert not (c.used & cloudy).any()
    assert not c.valid[invalid].any() and np.isnan(c.zenith_error_deg[invalid]).all()
    assert c.summary.zenith.rms == pytest.approx(SIGMA, rel=0.2)
    assert np.nanmean(np.abs(c.zenith_error_deg[cloudy & c.in_fov])) > 0.2
    assert any("cloud-flagged" in n for n in c.notes)
    # a heading fit over the default mask ignores the clouds too
    fit = compare_with_sun(TIMES, th, ph, SITE, Mount(0.0), ATM, heading="fit", cloudy=cloudy)
    assert fit.mount_fit.n_samples == c.summary.count


def test_warnings_near_the_boresight_and_with_too_few_samples():
    # the Sun through the zenith: the Tropic of Cancer at the June solstice, local noon
    sky = SimulatedSky(23.44, 0.0, 0.0, delta_t_s=69.0)
    t = float(utc_seconds("2021-06-21T12:00:00")[0]) + np.arange(-1800.0, 1800.0, 60.0)
    th, ph = readings(sky, SimulatedMount(0.0), t, 0.01, np.random.default_rng(33))
    c = compare_with_sun(t, th, ph, site_of(sky), Mount(0.0), atmosphere_of(sky))
    assert c.sun_zenith_deg.min() < 1.0
    assert any("boresight" in w for w in c.warnings)
    assert any("sky's zenith" in w for w in c.warnings)
    assert c.summary.azimuth.count < c.summary.count  # the ill-defined azimuths are left out
    few = compare_with_sun(t[:5], th[:5], ph[:5], site_of(sky), Mount(0.0), atmosphere_of(sky))
    assert any("only 5 clear sample(s)" in w for w in few.warnings)


def test_typed_errors():
    th = np.full(TIMES.size, 40.0)
    with pytest.raises(FieldDataError, match="one length"):
        compare_with_sun(TIMES, th[:-1], th, SITE)
    with pytest.raises(FieldDataError, match="cloudy"):
        compare_with_sun(TIMES, th, th, SITE, cloudy=np.zeros(3, bool))
    with pytest.raises(FieldDataError, match="heading"):
        compare_with_sun(TIMES, th, th, SITE, heading="compass")
    with pytest.raises(FieldDataError, match="no valid sample"):
        compare_with_sun(TIMES, th, th, SITE, heading="fit", cloudy=np.ones(TIMES.size, bool))
    c = compare_with_sun([str(np.datetime64(int(TIMES[0]), "s"))], [40.0], [10.0], Site(54.84, 83.09))
    assert c.times_s[0] == TIMES[0]
