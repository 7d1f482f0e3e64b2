"""The simulated field (drivers/sim/sky.py, drivers/sim/field.py): the Sun over a site through the mount into the
sensor, clouds that dim it and move its spot, all through the CMOS module's own simulator and driver."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration.centroid import find_spot
from calibration.field.sky import Atmosphere, Mount, Site, sensor_from_sky, sun_position, utc_seconds
from drivers.cmos_sensor import CmosSunSensor
from drivers.sim import registry
from drivers.sim.cmos_sensor import CmosSensorSimulator
from drivers.sim.field import field_world
from drivers.sim.raytrace import spot_moments, spot_patch
from drivers.sim.sky import SUN_DIAMETER_DEG, CloudBank, CloudState, SimulatedMount, SimulatedSky
from drivers.sim.world import EXAMPLE_OPTICS
from drivers.transport import open_port

START = float(utc_seconds(["2019-09-29T03:58:17Z"])[0])
SKY = SimulatedSky(54.8437, 83.0930, 160.0, pressure_hpa=1000.0, temperature_c=12.0, delta_t_s=69.0)


def test_the_sun_reaches_the_sensor_through_the_true_mount():
    """The field world's Sun in the body frame is SPA's apparent Sun turned by the mount (two codes: the
    simulator's Rodrigues rotations and calibration/field's matrices, one convention)."""
    mount = SimulatedMount(heading_deg=12.0, roll_deg=0.4, pitch_deg=-0.3)
    world = field_world(SKY, mount, START)
    for offset in (0.0, 3600.0, 7200.0):
        world.clock.advance_to(offset)
        zenith, azimuth = world.sun_direction_body()
        sun = sun_position([START + offset], Site(54.8437, 83.0930, 160.0), Atmosphere(1000.0, 12.0, 69.0))
        want_z, want_a = sensor_from_sky(sun.apparent_zenith_deg, sun.azimuth_deg, Mount(12.0, 0.4, -0.3))
        assert zenith == pytest.approx(float(want_z[0]), abs=1e-6)
        assert azimuth == pytest.approx(float(want_a[0]), abs=1e-6)


def test_a_cloud_edge_moves_the_spot_away_from_the_covered_side():
    """Half the disc covered: the spot's centroid moves by the centroid of the visible half-disc, 4r/(3π) of
    the Sun's angular radius, towards the uncovered side (a uniform disc; the pinhole maps angles to pixels by the
    local Jacobian, measured here from two clear spots)."""
    zenith, azimuth = 30.0, 40.0
    clear = spot_moments(spot_patch(zenith, azimuth, EXAMPLE_OPTICS, source_diameter_deg=SUN_DIAMETER_DEG))
    # edge angle 0: the covered side is along the body's +x seen at the Sun
    half = spot_moments(spot_patch(zenith, azimuth, EXAMPLE_OPTICS, source_diameter_deg=SUN_DIAMETER_DEG,
                                   occlusion=(0.0, 0.0, 0.0)))
    shift_px = np.hypot(half[0] - clear[0], half[1] - clear[1])
    # the spot of a source 0.01° away along the same tangent direction, for the px per degree there
    sun = np.array([math.sin(math.radians(zenith)) * math.cos(math.radians(azimuth)),
                    math.sin(math.radians(zenith)) * math.sin(math.radians(azimuth)), math.cos(math.radians(zenith))])
    e1 = np.array([1.0, 0, 0]) - sun[0] * sun
    e1 /= np.linalg.norm(e1)
    moved = sun - math.radians(0.01) * e1  # away from the covered side
    mz = math.degrees(math.acos(moved[2] / np.linalg.norm(moved)))
    ma = math.degrees(math.atan2(moved[1], moved[0]))
    ref = spot_moments(spot_patch(mz, ma, EXAMPLE_OPTICS, source_diameter_deg=SUN_DIAMETER_DEG))
    px_per_deg = np.hypot(ref[0] - clear[0], ref[1] - clear[1]) / 0.01
    expected_deg = 4 * (SUN_DIAMETER_DEG / 2) / (3 * math.pi)
    assert shift_px / px_per_deg == pytest.approx(expected_deg, rel=0.05)
    # and in the same direction as a source moved away from the covered side
    along = np.dot([half[0] - clear[0], half[1] - clear[1]], [ref[0] - clear[0], ref[1] - clear[1]])
    assert along > 0


def test_cloud_banks_cover_then_uncover_the_disc():
    bank = CloudBank(start_s=1000.0, duration_s=600.0, speed_deg_s=0.002, direction_deg=30.0, transmission=0.1)
    r = SUN_DIAMETER_DEG / 2
    assert bank.state(1000.0 - 3 * r / 0.002 - 1) is None  # far away
    arriving = bank.state(1000.0)
    assert arriving.covered_fraction() == pytest.approx(0.5, abs=1e-6) and arriving.edge_angle_deg == 30.0
    assert bank.state(1300.0).covered_fraction() == 1.0
    leaving = bank.state(1600.0)
    assert leaving.covered_fraction() == pytest.approx(0.5, abs=1e-6) and leaving.edge_angle_deg == 210.0
    assert CloudState().clear and not arriving.clear


def test_a_field_day_through_the_cmos_driver_dims_and_moves_under_cloud():
    """The CMOS module's simulator on a field world, read through its driver: clear spots follow the Sun, a
    half-covered Sun dims the spot by about half and moves it."""
    bank = CloudBank(start_s=START + 1800.0, duration_s=600.0, direction_deg=0.0, transmission=0.0, aureole=0.0)
    sky = SimulatedSky(SKY.latitude_deg, SKY.longitude_deg, SKY.altitude_m, pressure_hpa=1000.0, temperature_c=12.0,
                       delta_t_s=69.0, clouds=(bank,))
    world = field_world(sky, SimulatedMount(12.0, 0.0, 0.0), START)
    url = registry.register("test-field-sensor", CmosSensorSimulator(world))
    try:
        sensor = CmosSunSensor(open_port(url))
        sensor.set_exposure_ms(2.0)
        world.clock.advance_to(1800.0 - 400.0)
        clear = find_spot(sensor.capture(), saturation_dn=1023)
        world.clock.advance_to(1800.0)
        half = find_spot(sensor.capture(), saturation_dn=1023)
        world.clock.advance_to(1800.0 + 300.0)
        with pytest.raises(Exception, match="[Nn]o spot|NoSpot"):
            find_spot(sensor.capture(), saturation_dn=1023)
    finally:
        registry.unregister("test-field-sensor")
    assert (half.peak_dn - half.background_dn) / (clear.peak_dn - clear.background_dn) == pytest.approx(0.5, abs=0.1)
    assert np.hypot(half.x_px - clear.x_px, half.y_px - clear.y_px) > 0.3


def test_random_clouds_over_an_interval_that_ends_before_it_starts_are_none():
    from drivers.sim.sky import random_clouds

    assert random_clouds(np.random.default_rng(0), 100.0, 50.0, banks_per_hour=60) == ()


def test_a_cloud_bank_narrower_than_the_sun_is_refused_and_random_banks_are_wider():
    with pytest.raises(ValueError, match="wider than the Sun"):
        CloudBank(start_s=0.0, duration_s=100.0, speed_deg_s=0.002)  # 0.2°: both edges on the disc at once
    from drivers.sim.sky import random_clouds

    banks = random_clouds(np.random.default_rng(1), 0.0, 36000.0, banks_per_hour=30, mean_duration_s=60.0)
    assert len(banks) > 100 and all(b.duration_s * b.speed_deg_s >= SUN_DIAMETER_DEG for b in banks)
