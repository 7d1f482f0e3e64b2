"""The Meade LX200 table driver against the simulated mount through a real ``sim://`` URL: the same driver
code as on hardware, with the world's truth and the fault back door to check what the wire cannot show."""

import itertools
import time
from uuid import uuid4

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, ProtocolError
from drivers.interfaces import Limits
from drivers.meade import LX200Table, MountBusy
from drivers.sim.clock import SimClock
from drivers.sim.lx200 import LX200Simulator
from drivers.sim.motion import AxisSpec, trapezoid
from drivers.sim.registry import register, unregister
from drivers.sim.world import SimWorld
from drivers.transport import open_port

AZ_SPEC = AxisSpec(max_rate_deg_s=10.0, accel_deg_s2=20.0, settle_s=0.05, soft_limits_deg=(0.0, 360.0))
ALT_SPEC = AxisSpec(max_rate_deg_s=10.0, accel_deg_s2=20.0, settle_s=0.05, soft_limits_deg=(-90.0, 90.0),
                    hard_limits_deg=(-10.0, 50.0))
ARCSEC = 1 / 3600


class FakeWall:
    """Wall time the test moves by hand, so a simulated move can be stopped at an exact instant."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture
def bench():
    """Factory: ``bench(time_scale=0, wall=None, **simulator_options)`` → (table, simulator, world)."""
    made = []

    def make(time_scale=0.0, wall=None, *, connect=True, limits=(Limits(0.0, 359.0), Limits(-5.0, 85.0)),
             **sim_options):
        clock = SimClock(time_scale, wall=wall) if wall else SimClock(time_scale)
        world = SimWorld(clock=clock)
        sim = LX200Simulator(world, AZ_SPEC, ALT_SPEC, **sim_options)
        name = f"lx200-{uuid4().hex[:12]}"  # a fresh simulator per test
        port = open_port(register(name, sim), baudrate=9600, timeout_s=0.1)
        made.append((name, port))
        table = LX200Table(port, *limits, nak_wait_s=0.001, nak_window_s=0.005, poll_s=0.002)
        if connect:
            table.connect()
        return table, sim, world

    yield make
    for name, port in made:
        port.close()
        unregister(name)


def test_connect_sets_alt_az_mode_and_high_precision(bench):
    table, sim, _ = bench(alignment="L", high_precision=False)
    assert sim.alignment == "A" and sim.high_precision is True and table.high_precision is True
    assert sim.received[:3] == [b"\x06", b"AA", b"\x06"]


def test_identify(bench):
    table, _, _ = bench(product="LX200GPS", firmware="4.2g")
    assert table.identify() == "LX200GPS 4.2g"


@pytest.mark.parametrize("high_precision, degree_sign", [(True, b"\xdf"), (False, b"\xdf"), (False, b"*")])
def test_move_both_axes_and_read_back(bench, high_precision, degree_sign):
    table, sim, world = bench(degree_sign=degree_sign)
    table.set_precision(high_precision)
    resolution = ARCSEC if high_precision else 1 / 60
    for azimuth, zenith in [(123.456, 33.3), (5.0, -4.5), (300.25, 0.0)]:
        table.move_to(azimuth, zenith, timeout_s=2.0)
        az, zen = table.position()
        # the target was rounded to the resolution when sent and the reading when read
        assert az == pytest.approx(azimuth, abs=resolution + 1e-9)
        assert zen == pytest.approx(zenith, abs=resolution + 1e-9)
        true_az, true_omega = world.stage_true_deg()  # the world's truth follows the table
        assert true_az == pytest.approx(azimuth, abs=resolution / 2 + AZ_SPEC.step_deg)
        assert true_omega == pytest.approx(zenith, abs=resolution / 2 + ALT_SPEC.step_deg)
    assert not table.is_moving()


def test_a_move_takes_simulated_time_at_time_scale_20(bench):
    table, _, world = bench(time_scale=20.0)
    t0_sim, t0 = world.clock.now(), time.monotonic()
    table.move_to(8.0, 5.0, wait=False)
    assert table.is_moving()
    table.wait_until_stopped(timeout_s=2.0)
    duration_s = trapezoid(8.0, 10.0, 20.0) + AZ_SPEC.settle_s  # the longer axis, plus settling
    assert world.clock.now() - t0_sim >= duration_s  # the bars showed until the move was done
    assert time.monotonic() - t0 >= duration_s / 20.0 * 0.9  # and it took wall time (clock granularity)
    assert table.position() == pytest.approx((8.0, 5.0), abs=ARCSEC)


def test_a_move_is_instant_at_time_scale_0(bench):
    table, _, world = bench(time_scale=0.0)
    t0 = time.monotonic()
    table.move_to(90.0, 45.0)
    assert time.monotonic() - t0 < 0.5
    assert world.clock.now() >= trapezoid(90.0, 10.0, 20.0)  # the clock jumped to the end of the move
    assert table.position() == pytest.approx((90.0, 45.0), abs=ARCSEC)


def test_stop_mid_move(bench):
    wall = FakeWall()
    table, sim, world = bench(time_scale=1.0, wall=wall)
    table.move_to(100.0, 40.0, wait=False)
    wall.t = 1.0  # 1 s into both moves: 0.5 s of acceleration to 10 °/s, then 0.5 s at 10 °/s
    table.stop()
    assert not table.is_moving()
    assert table.position() == pytest.approx((7.5, 7.5), abs=ARCSEC)
    wall.t = 5.0
    assert table.position() == pytest.approx((7.5, 7.5), abs=ARCSEC)  # it stays stopped
    assert world.stage_true_deg() == pytest.approx((7.5, 7.5), abs=1e-4)


def test_stalled_axis_that_still_answers_ends_the_wait_in_device_timeout(bench):
    table, sim, _ = bench()
    sim.azimuth.stall()
    table.move_to(30.0, 10.0, wait=False)
    with pytest.raises(DeviceTimeout, match="stalled"):
        table.wait_until_stopped(timeout_s=0.05)
    assert sim.received[-1] == b"Q"  # the driver stopped the mount
    assert not sim.azimuth.busy() and not table.is_moving()


def test_limit_switch_stops_the_move_short_and_is_a_device_fault(bench):
    table, sim, _ = bench()
    with pytest.raises(DeviceFault, match="stopped at"):
        table.move_to(20.0, 60.0)  # the altitude hard limit switch sits at 50°
    assert sim.altitude.limit_hit == "high"
    assert table.position()[1] == pytest.approx(50.0, abs=ARCSEC)
    table.move_to(20.0, 10.0)  # moving off the switch works
    assert sim.altitude.limit_hit is None


def test_tripped_limit_switch_refuses_the_slew(bench):
    table, sim, _ = bench()
    table.move_to(10.0, 10.0)
    sim.altitude.trip_limit("high")
    with pytest.raises(DeviceFault, match="refused"):
        table.move_to(10.0, 20.0)  # further into the switch: :MA# answers the fault char
    assert not table.is_moving()


def test_no_reply_is_a_device_timeout(bench):
    table, sim, _ = bench()
    sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout) as err:
        table.position()
    assert err.value.received == b""


@pytest.mark.parametrize("fault", ["garble", "truncate"])
def test_one_bad_reply_is_retried_cleanly(bench, fault):
    table, sim, _ = bench()
    table.move_to(12.5, 20.25)
    setattr(sim.faults, fault, 1)
    assert table.position() == pytest.approx((12.5, 20.25), abs=ARCSEC)
    assert getattr(sim.faults, fault) == 0


@pytest.mark.parametrize("fault", ["garble", "truncate"])
def test_persistent_bad_replies_raise_typed_errors_never_a_reading(bench, fault):
    table, sim, _ = bench()
    table.move_to(12.5, 20.25)
    commands = [table.altitude_deg, table.mount_azimuth_deg]
    if fault == "garble":  # cutting a one-byte reply ("A", "#") in half leaves it whole
        commands += [table.probe, table.is_moving]
    for command in commands:
        setattr(sim.faults, fault, 10)
        with pytest.raises((ProtocolError, DeviceTimeout)) as err:
            command()
        assert err.value.received  # the error carries the bytes that did arrive


def test_busy_naks_are_retried(bench):
    table, sim, _ = bench()
    sim.busy_naks = 3
    table.move_to(15.0, 5.0)
    assert sim.busy_naks == 0
    assert table.position() == pytest.approx((15.0, 5.0), abs=ARCSEC)


def test_busy_forever_is_mount_busy(bench):
    table, sim, _ = bench()
    sim.busy_naks = 100
    with pytest.raises(MountBusy):
        table.position()


def test_disconnect_is_device_disconnected(bench):
    table, sim, _ = bench()
    sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        table.position()
    with pytest.raises(DeviceDisconnected):
        table.stop()


def test_simulator_framing_ignores_a_leading_hash_noise_and_unknown_commands(bench):
    table, sim, _ = bench(connect=False, high_precision=True)
    port = table.port
    assert port.query(b"#:GA#", b"#") == b"+00\xdf00:00#"  # Meade's flushing '#' (research note §1.1)
    assert port.query(b"\x00:GZ#", b"#") == b"000\xdf00:00#"
    port.write(b":XYZ#:Sw5#")  # unknown (and unmodelled) commands: no reply at all
    with pytest.raises(DeviceTimeout):
        port.read_exact(1, timeout_s=0.02)
    port.write(b":G")  # a partial frame waits…
    port.write(b"Z#")  # …and completes across writes
    assert port.read_until(b"#") == b"000\xdf00:00#"


def test_simulator_set_commands_use_the_shared_ok_chars(bench):
    table, sim, _ = bench(connect=False)
    port = table.port
    for command, reply in [(b":Sa+95*00#", b"0"), (b":Sa+45*00#", b"1"), (b":Sz360*00#", b"0"),
                           (b":Sz010\xdf30:15#", b"1"), (b":MA#", b"0")]:
        port.write(command)
        assert port.read_exact(1) == reply, command
    assert (sim.target_azimuth_deg, sim.target_altitude_deg) == pytest.approx((10.5 + 15 / 3600, 45.0))


def test_world_azimuth_follows_a_signed_soft_limit_window(bench):
    table, _, world = bench(limits=(Limits(-180.0, 180.0), Limits(-5.0, 85.0)))
    table.move_to(-20.0, 10.0)
    assert table.position() == pytest.approx((-20.0, 10.0), abs=ARCSEC)
    assert world.stage_true_deg()[0] % 360.0 == pytest.approx(340.0, abs=ARCSEC)


def test_many_moves_stay_deterministic(bench):
    table, _, world = bench()
    for azimuth, zenith in itertools.product((0.0, 45.0, 270.0), (-5.0, 30.0, 49.0)):
        table.move_to(azimuth, zenith)
        assert table.position() == pytest.approx((azimuth, zenith), abs=ARCSEC)
