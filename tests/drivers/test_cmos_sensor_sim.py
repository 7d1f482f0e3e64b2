"""The CMOS module driver against its simulator through a sim:// port: the spot follows the table."""

import itertools

import numpy as np
import pytest
from framedtools import inject

from calibration.centroid import NoSpotError, SaturatedSpotError, find_spot
from calibration.geometry import angular_error_deg
from calibration.pinhole import direction_from_spot
from drivers.cmos_sensor import CmosSunSensor
from drivers.errors import ChecksumError, DeviceDisconnected, DeviceTimeout, ProtocolError
from drivers.sim import registry
from drivers.sim.clock import SimClock
from drivers.sim.cmos_sensor import CmosSensorSimulator
from drivers.sim.motion import AxisSpec
from drivers.sim.raytrace import trace_chief_ray
from drivers.sim.world import SimWorld
from drivers.transport import open_port

_names = itertools.count()


@pytest.fixture
def bench(request):
    time_scale = getattr(request, "param", 0.0)
    world = SimWorld(clock=SimClock(time_scale), seed=3)
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    world.lamp.start()
    world.lamp.is_warm()
    world.lamp.shutter_open = True
    sim = CmosSensorSimulator(world)
    name = f"cmos-test-{next(_names)}"
    url = registry.register(name, sim)
    sensor = CmosSunSensor(open_port(url, baudrate=921600, timeout_s=0.3), frame_timeout_s=0.5)
    yield world, sim, sensor
    sensor.port.close()
    registry.unregister(name)


def _truth(world):
    zenith, azimuth = world.sun_direction_body()
    x, y = trace_chief_ray(zenith, azimuth, world.sensor.optics)  # the simulator's own physics
    return zenith, azimuth, x, y


def test_the_spot_follows_the_table_as_the_world_says(bench):
    world, _, sensor = bench
    sensor.set_exposure_ms(4.0)
    for azimuth, omega in [(0, 0), (45, 10), (90, 25), (200, 40), (315, 50)]:
        world.azimuth.move_to(azimuth)
        world.zenith.move_to(omega)
        spot = find_spot(sensor.capture(), saturation_dn=1023)
        zenith, az, x, y = _truth(world)
        # one frame's centroid noise is ~0.015 px (0.035 px at 60°)
        assert np.hypot(spot.x_px - x, spot.y_px - y) < 0.06
        seen = direction_from_spot(spot.x_px, spot.y_px, world.sensor.optics, world.sensor.design.pixel_pitch_mm)
        assert angular_error_deg(zenith, az, *seen) < 0.03


def test_onboard_centroid_agrees_with_the_library(bench):
    world, _, sensor = bench
    world.zenith.move_to(20)
    onboard = sensor.onboard_centroid()
    spot = find_spot(sensor.capture(), saturation_dn=1023)
    assert onboard.status == "ok"
    assert np.hypot(onboard.x_px - spot.x_px, onboard.y_px - spot.y_px) < 0.05


def test_closed_shutter_and_overexposure(bench):
    world, _, sensor = bench
    world.lamp.shutter_open = False
    with pytest.raises(NoSpotError):
        find_spot(sensor.capture(), saturation_dn=1023)
    assert sensor.onboard_centroid().status == "no spot"
    world.lamp.shutter_open = True
    sensor.set_exposure_ms(40.0)
    with pytest.raises(SaturatedSpotError):
        find_spot(sensor.capture(), saturation_dn=1023)
    assert sensor.onboard_centroid().status == "saturated spot"


def test_frames_are_noisy_but_reproducible():
    def frames(seed):
        world = SimWorld(seed=seed)
        world.lamp.start(), world.lamp.is_warm()
        world.lamp.shutter_open = True
        renderer = CmosSensorSimulator(world).renderer
        return renderer.render(4.0), renderer.render(4.0)

    a1, a2 = frames(5)
    b1, _ = frames(5)
    assert not np.array_equal(a1, a2)
    np.testing.assert_array_equal(a1, b1)
    assert a1.max() <= 1023 and (a1 == 0).sum() >= 5  # 10-bit, dead pixels


def test_capture_takes_exposure_and_readout_in_simulated_time(bench):
    world, sim, sensor = bench
    sensor.set_exposure_ms(4.0)
    t0 = world.clock.now()
    sensor.capture()
    assert world.clock.now() - t0 == pytest.approx((4.0 + sim.renderer.spec.readout_ms) / 1000.0)


@pytest.mark.parametrize("bench", [1.0], indirect=True)
def test_capture_reply_waits_for_the_exposure_in_real_time(bench):
    world, _, sensor = bench
    sensor.set_exposure_ms(100.0)
    t0 = world.clock.now()
    image = sensor.capture()
    assert world.clock.now() - t0 >= 0.108 and image.shape == (480, 640)


@pytest.mark.parametrize("fault", ["garble", "truncate", "corrupt_crc"])
def test_one_bad_reply_is_a_counted_retry(bench, fault):
    world, sim, sensor = bench
    inject(sim, fault, 1)
    assert sensor.temperature_c() == pytest.approx(world.temperature_c)
    inject(sim, fault, 1)
    image = sensor.capture()  # a capture is asked for again, a new exposure
    assert image.shape == (480, 640)
    assert sensor.retry_count == 2


@pytest.mark.parametrize("fault, error", [("no_reply", DeviceTimeout), ("garble", ProtocolError),
                                          ("truncate", DeviceTimeout), ("corrupt_crc", ChecksumError)])
def test_faults_give_typed_errors_then_a_clean_exchange(bench, fault, error):
    world, sim, sensor = bench
    inject(sim, fault, sensor.retries + 1)  # one more bad reply than the driver retries
    with pytest.raises(error, match=sensor.name) as info:
        sensor.temperature_c()
    assert info.value.attempts == sensor.retries + 1
    sim.faults.clear()
    assert sensor.temperature_c() == pytest.approx(world.temperature_c)
    spot = find_spot(sensor.capture(), saturation_dn=1023)
    assert np.hypot(spot.x_px - _truth(world)[2], spot.y_px - _truth(world)[3]) < 0.1


def test_disconnect(bench):
    _, sim, sensor = bench
    sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        sensor.identify()


def test_a_bad_crc_from_the_host_gets_an_error_frame(bench):
    _, sim, _ = bench
    from drivers import cmos_protocol as wire
    raw = bytearray(wire.encode_frame(wire.TEMPERATURE, 5))
    raw[-1] ^= 0xFF
    reply = sim.receive(bytes(raw))
    frame, _ = wire.decode_frame(reply)
    assert frame.code == wire.ERROR and frame.sequence == 5 and frame.payload[0] == 3
