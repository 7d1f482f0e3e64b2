"""The Sun's computed position (NREL SPA via pvlib) and the mount's frames (calibration.field.sky), checked
against SPA's published reference case and against the field simulator's independent code."""

import datetime as dt
import math

import numpy as np
import pytest
from field_simulation import PISEK_SKY, atmosphere_of, site_of, track_times

from calibration.errors import FieldDataError
from calibration.field.sky import (
    NREL_REFERENCE,
    Atmosphere,
    Mount,
    Site,
    mount_from_gravity,
    sensor_from_sky,
    sky_from_sensor,
    sun_position,
    utc_seconds,
)
from calibration.geometry import wrap_deg
from drivers.sim.sky import SimulatedMount, SimulatedSky

REF = NREL_REFERENCE
REF_SITE = Site(REF["latitude_deg"], REF["longitude_deg"], REF["altitude_m"])
REF_AIR = Atmosphere(pressure_hpa=REF["pressure_hpa"], temperature_c=REF["temperature_c"], delta_t_s=REF["delta_t_s"])


def test_nrel_reference_case_to_1e_4_degree():
    """Reda & Andreas (2004) table A4.1: Golden, Colorado, 2003-10-17 12:30:30 UTC−7."""
    sun = sun_position([REF["time_utc"]], REF_SITE, REF_AIR)
    assert abs(sun.apparent_zenith_deg[0] - REF["zenith_deg"]) < 1e-4
    assert abs(sun.azimuth_deg[0] - REF["azimuth_deg"]) < 1e-4


@pytest.mark.parametrize("when", [
    dt.datetime(2003, 10, 17, 12, 30, 30, tzinfo=dt.timezone(dt.timedelta(hours=-7))),
    "2003-10-17T12:30:30-07:00",
    "2003-10-17 19:30:30",  # no zone: UTC
    np.datetime64("2003-10-17T19:30:30"),
])
def test_the_reference_instant_through_zones_and_types(when):
    sun = sun_position([when], REF_SITE, REF_AIR)
    assert abs(sun.apparent_zenith_deg[0] - REF["zenith_deg"]) < 1e-4
    assert abs(sun.azimuth_deg[0] - REF["azimuth_deg"]) < 1e-4
    assert utc_seconds([when])[0] == pytest.approx(utc_seconds(REF["time_utc"])[0], abs=1e-6)


def test_numeric_times_are_unix_seconds():
    t = utc_seconds(REF["time_utc"])
    a = sun_position(t, REF_SITE, REF_AIR)
    assert a.apparent_zenith_deg[0] == pytest.approx(REF["zenith_deg"], abs=1e-4)


@pytest.mark.parametrize("make, column", [
    (lambda: Site(90.5, 0.0), "latitude_deg"),
    (lambda: Site(-91.0, 0.0), "latitude_deg"),
    (lambda: Site(10.0, 400.0), "longitude_deg"),
    (lambda: Site(10.0, -181.0), "longitude_deg"),
    (lambda: Site(10.0, 10.0, 12000.0), "altitude_m"),
    (lambda: Atmosphere(pressure_hpa=-1.0), "pressure_hpa"),
    (lambda: Atmosphere(pressure_hpa=1200.0), "pressure_hpa"),
    (lambda: Atmosphere(temperature_c=80.0), "temperature_c"),
])
def test_typed_errors_of_site_and_atmosphere(make, column):
    with pytest.raises(FieldDataError) as info:
        make()
    assert info.value.column == column


def test_utc_seconds_names_the_bad_time():
    with pytest.raises(FieldDataError) as info:
        utc_seconds(["2013-04-18T08:00:00", "yesterday noon"])
    assert info.value.row == 1 and info.value.column == "time_utc"
    assert "yesterday noon" in str(info.value)


def test_spa_agrees_with_the_simulators_own_refraction():
    """Two codes for the apparent Sun: SPA's refraction term (calibration) and the simulator's airless SPA bent
    by its own Sæmundsson refraction; with the same air they agree far below any sensor's noise."""
    t = track_times(step_s=600.0, hours=10.0, start_s=track_times()[0] - 4 * 3600)
    sun = sun_position(t, site_of(PISEK_SKY), atmosphere_of(PISEK_SKY))
    z, a = PISEK_SKY.apparent_position(t)
    up = z < 89.0
    assert np.max(np.abs(sun.apparent_zenith_deg[up] - z[up])) < 1e-8
    assert np.max(np.abs(wrap_deg(sun.azimuth_deg[up] - a[up]))) < 1e-8
    # and the airless simulator differs by the refraction, so the test above is not trivially true
    airless = SimulatedSky(PISEK_SKY.latitude_deg, PISEK_SKY.longitude_deg, PISEK_SKY.altitude_m,
                           pressure_hpa=0.0, delta_t_s=PISEK_SKY.delta_t_s).apparent_position(t)[0]
    assert np.max(np.abs(airless[up] - z[up])) > 0.01


ANGLES = np.random.default_rng(11).uniform([0, -8, -8], [360, 8, 8], size=(20, 3))


@pytest.mark.parametrize("heading, roll, pitch", [tuple(a) for a in ANGLES] + [(0, 0, 0), (90, 30, -45)])
def test_mount_matrix_is_the_simulators_mount(heading, roll, pitch):
    """Two codes, one convention: Mount.matrix (H·Rx·Ry) and SimulatedMount's Rodrigues rotations."""
    ours = Mount(heading, roll, pitch).matrix()
    theirs = SimulatedMount(heading, roll, pitch).sensor_axes_enu()
    assert np.max(np.abs(ours - theirs)) < 1e-12


def test_sensor_sky_round_trip_and_the_level_convention():
    rng = np.random.default_rng(5)
    z = rng.uniform(1.0, 89.0, 200)
    a = rng.uniform(0.0, 360.0, 200)
    for heading, roll, pitch in ANGLES[:6]:
        mount = Mount(heading, roll, pitch)
        th, ph = sensor_from_sky(z, a, mount)
        z2, a2 = sky_from_sensor(th, ph, mount)
        assert np.max(np.abs(z2 - z)) < 1e-9
        assert np.max(np.abs(wrap_deg(a2 - a))) < 1e-9
    # a level mount: θ is the zenith, φ = ψ − A (the sensor's +y is 90° anticlockwise of +x seen from above)
    th, ph = sensor_from_sky(z, a, Mount(17.3))
    assert np.max(np.abs(th - z)) < 1e-9
    assert np.max(np.abs(wrap_deg(ph - (17.3 - a)))) < 1e-9


@pytest.mark.parametrize("roll, pitch", [(0.0, 0.0), (0.4, -0.3), (-5.0, 12.0), (30.0, 60.0)])
def test_mount_from_gravity_inverts_the_mount(roll, pitch):
    m = Mount(123.0, roll, pitch).matrix()
    up_sensor = m.T @ np.array([0.0, 0.0, 1.0])
    gravity = -9.81 * up_sensor  # what an accelerometer at rest reads is −g·up; the function takes up
    back = mount_from_gravity(-gravity, heading_deg=123.0)
    assert back.roll_deg == pytest.approx(roll, abs=1e-9)
    assert back.pitch_deg == pytest.approx(pitch, abs=1e-9)
    assert np.max(np.abs(back.matrix() - m)) < 1e-12
    with pytest.raises(FieldDataError):
        mount_from_gravity([0.0, 0.0, 0.0])
    with pytest.raises(FieldDataError):
        mount_from_gravity([math.nan, 0.0, 1.0])
