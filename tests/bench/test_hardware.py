"""connect_bench: a bench file becomes connected devices — every kind of simulated table and source, a
manual table with real (here: served elsewhere) devices — and a device that cannot be opened is named."""

import pytest

import bench.hardware as hardware
import drivers.thorlabs_apt as thorlabs_apt
from bench.benchfile import BenchFile, parse_bench_file
from bench.hardware import BenchConnectionError, connect_bench
from calibration.centroid import find_spot
from calibration.geometry import angular_error_deg
from calibration.pinhole import direction_from_spot
from drivers.errors import DeviceDisconnected
from drivers.sim import registry
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.transport import open_port


def _registered() -> set[str]:
    return set(registry._devices)


def _spot_matches_the_world(devices) -> tuple[float, float]:
    """Capture a frame; its spot must be where the simulated world puts the sun."""
    spot = find_spot(devices.sensor.capture(), saturation_dn=1023)
    world = devices.sim.world
    measured = direction_from_spot(spot.x_px, spot.y_px, world.sensor.optics, world.sensor.design.pixel_pitch_mm)
    assert angular_error_deg(*world.sun_direction_body(), *measured) < 0.05
    return spot.x_px, spot.y_px


@pytest.mark.parametrize("table, source", [("apt", "xenon"), ("smc100", "led"), ("lx200", "xenon"), ("lx200", "led")])
def test_connect_a_simulated_bench_and_measure(table, source):
    before = _registered()
    bench_file = parse_bench_file({"simulation": {"table": table, "source": source, "seed": 1}})
    devices = connect_bench(bench_file, time_scale=0.0)
    try:
        assert devices.simulated and devices.sim.world.clock.instant  # time_scale overrides the file's 1.0
        assert set(devices.identities) == {"table", "source", "sensor"} and all(devices.identities.values())
        assert "SIM-0001" in devices.identities["sensor"]
        # the supply times the warm-up on the simulated clock with the simulated lamp's warm time
        supply = devices.source.supply
        assert supply.clock() == devices.sim.world.clock.now()
        assert devices.source.warmup_s == devices.sim.world.lamp.spec.warm_time_s

        devices.table.move_to(0.0, 0.0)
        devices.source.lamp_on()
        devices.source.wait_until_warm(timeout_s=5.0, poll_s=0.0)
        devices.source.open_shutter()
        status = devices.source.status()
        assert status.warm and status.shutter_open and not status.fault
        devices.sensor.set_exposure_ms(4.0)
        first = _spot_matches_the_world(devices)
        devices.table.move_to(90.0, 20.0)
        assert devices.table.position() == (pytest.approx(90.0, abs=0.02), pytest.approx(20.0, abs=0.02))
        second = _spot_matches_the_world(devices)
        assert abs(first[0] - second[0]) + abs(first[1] - second[1]) > 20  # the spot moved with the table
    finally:
        devices.close()
    assert _registered() == before  # close() unregistered the simulators
    devices.close()  # twice is harmless


def test_close_unregisters_and_a_second_connect_works():
    devices = connect_bench(BenchFile(), time_scale=0.0)
    names = _registered()
    devices.close()
    gone = names - _registered()
    assert len(gone) == len(devices.sim.devices) == 5  # table axes, lamp, shutter, sensor
    for name in gone:
        with pytest.raises(DeviceDisconnected):
            open_port(f"sim://{name}")
    with connect_bench(BenchFile(), time_scale=0.0) as again:
        again.table.move_to(10.0, 5.0)
        assert again.table.position() == (pytest.approx(10.0, abs=0.02), pytest.approx(5.0, abs=0.02))


def test_simulated_smc100_answers_the_configured_addresses():
    bench_file = parse_bench_file({"simulation": {"table": "smc100"},
                                   "devices": {"table": {"azimuth": {"address": 3}, "zenith": {"address": 7}}}})
    with connect_bench(bench_file, time_scale=0.0) as devices:
        assert (devices.table.azimuth.address, devices.table.zenith.address) == (3, 7)
        devices.table.move_to(45.0, 10.0)
        assert devices.table.position() == (pytest.approx(45.0, abs=0.02), pytest.approx(10.0, abs=0.02))


def test_manual_table_with_devices_given_by_url():
    """No simulation section: the source and sensor are opened at the URLs given (here simulators served by
    the test), the lamp is timed on the wall clock with the file's warm-up, the manual axes ask."""
    served = SimBench(SimBenchConfig(time_scale=0.0))
    urls = served.register()
    asked = []

    def ask(axis_name, target_deg):
        asked.append((axis_name, target_deg))
        return target_deg + 0.01  # the operator reads the scale a little off

    bench_file = parse_bench_file({"devices": {
        "table": {"kind": "manual", "zenith": {"limits_deg": [0, 60]}},
        "source": {"kind": "xenon", "lamp_url": urls["lamp"], "shutter_url": urls["shutter"], "warmup_s": 0.0},
        "sensor": {"kind": "cmos", "url": urls["sensor"]}}})
    try:
        with connect_bench(bench_file, time_scale=0.0, ask=ask) as devices:
            assert not devices.simulated and devices.sim is None
            assert devices.identities["table"] == ("azimuth: manual stage azimuth stage; "
                                                   "zenith: manual stage zenith stage")
            assert asked == []  # a manual table is not homed at connection
            devices.table.move_to(30.0, 15.0)
            assert asked == [("azimuth stage", 30.0), ("zenith stage", 15.0)]
            assert devices.table.position() == (pytest.approx(30.01), pytest.approx(15.01))
            devices.source.lamp_on()
            devices.source.wait_until_warm(timeout_s=5.0, poll_s=0.0)
            assert devices.source.warmup_s == 0.0
            assert "SIM-0001" in devices.identities["sensor"]
    finally:
        served.unregister()


@pytest.mark.parametrize("devices_section, role, url", [
    ({"sensor": {"url": "sim://no-such-sensor"}}, "sensor", "sim://no-such-sensor"),
    ({"table": {"zenith": {"url": "/dev/no-such-port"}}}, "table-zenith", "/dev/no-such-port"),
    ({"source": {"shutter_url": "sim://no-such-shutter"}}, "shutter", "sim://no-such-shutter"),
])
def test_a_bad_url_names_the_role_and_closes_what_was_opened(monkeypatch, devices_section, role, url):
    opened = []

    def recording_open_port(*args, **kwargs):
        port = open_port(*args, **kwargs)
        opened.append(port)
        return port

    monkeypatch.setattr(hardware, "open_port", recording_open_port)
    monkeypatch.setattr(thorlabs_apt, "open_port", recording_open_port)  # AptRotationStage.open's own
    before = _registered()
    bench_file = parse_bench_file({"simulation": {}, "devices": devices_section})
    with pytest.raises(BenchConnectionError) as info:
        connect_bench(bench_file, time_scale=0.0)
    error = info.value
    assert error.role == role and error.url == url
    assert role in str(error) and url in str(error)
    assert isinstance(error.cause, DeviceDisconnected)
    assert _registered() == before  # the simulators are unregistered
    assert opened  # the azimuth stage at least was open when the failure came
    assert all(not port.raw.is_open for port in opened)  # and every port opened before is closed


@pytest.mark.parametrize("table, source", [("apt", "xenon"), ("smc100", "led"), ("lx200", "xenon")])
def test_every_link_of_the_bench_retries_a_bad_reply_the_same_bounded_number_of_times(table, source):
    """Issue 10, item 10: one garbled or late reply does not fail a run on any link (drivers.transport)."""
    from drivers.transport import DEFAULT_RETRIES

    devices = connect_bench(parse_bench_file({"simulation": {"table": table, "source": source}}), time_scale=0.0)
    try:
        t = devices.table
        links = [t] if table == "lx200" else [t.azimuth, t.zenith]
        links += [devices.source.supply, devices.sensor] + ([devices.source.shutter] if source == "xenon" else [])
        assert [link.retries for link in links] == [DEFAULT_RETRIES] * len(links), [type(x).__name__ for x in links]
    finally:
        devices.close()
