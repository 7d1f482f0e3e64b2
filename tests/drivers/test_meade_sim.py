"""The Meade LX200 table driver against the simulated mount through a real ``sim://`` URL: the same driver
code as on hardware, with the world's truth and the fault back door to check what the wire cannot show."""

import itertools
import random
import time
from datetime import UTC, datetime, timedelta
from uuid import uuid4

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, ProtocolError
from drivers.interfaces import Limits
from drivers.meade import INDI_OK_CHARS, OK_CHARS, LX200Table, MountBusy, format_sexagesimal
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.clock import SimClock
from drivers.sim.lx200 import (
    SIDEREAL_RATE_DEG_S,
    LX200Simulator,
    equatorial_to_horizontal,
    greenwich_sidereal_time_deg,
    horizontal_to_equatorial,
)
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


# -- issue 11: what INDI's LX200 drivers send (sky, site, time, goto, moves, park) ----------------------------
J2000 = datetime(2000, 1, 1, 12, 0, 0, tzinfo=UTC)


def _query(port, command: bytes, n: int | None = None) -> bytes:
    port.write(command)
    return port.read_exact(n) if n else port.read_until(b"#")


def test_sidereal_time_matches_meeus():
    # Meeus, Astronomical Algorithms, example 12.a: 1987 April 10, 0h UT → GMST 13h10m46.3668s
    assert greenwich_sidereal_time_deg(datetime(1987, 4, 10, tzinfo=UTC)) / 15.0 == pytest.approx(
        13 + 10 / 60 + 46.3668 / 3600, abs=0.02 / 3600)
    assert greenwich_sidereal_time_deg(J2000) == pytest.approx(280.46061837)


def test_horizontal_and_equatorial_conversions_are_inverse_and_right_at_landmarks():
    rng = random.Random(11)
    for _ in range(500):
        alt, az, lat, lst = rng.uniform(-89, 89), rng.uniform(0, 360), rng.uniform(-89, 89), rng.uniform(0, 360)
        ra, dec = horizontal_to_equatorial(alt, az, lat, lst)
        assert equatorial_to_horizontal(ra, dec, lat, lst) == pytest.approx((alt, az), abs=1e-7)
    lat, lst = 54.85, 100.0
    assert horizontal_to_equatorial(90.0, 0.0, lat, lst) == pytest.approx((lst, lat))  # zenith: RA = LST
    assert horizontal_to_equatorial(lat, 0.0, lat, lst)[1] == pytest.approx(90.0)  # north at the latitude: pole
    assert horizontal_to_equatorial(0.0, 180.0, lat, lst) == pytest.approx((lst, lat - 90.0))  # south horizon
    ra, dec = horizontal_to_equatorial(0.0, 90.0, lat, lst)  # due east on the horizon: rising, 6 h east
    assert (ra, dec) == pytest.approx(((lst + 90.0) % 360.0, 0.0), abs=1e-9)


@pytest.mark.parametrize("high_precision, ra, dec", [(True, b"18:41:51#", b"+54\xdf51:00#"),
                                                     (False, b"18:41.8#", b"+54\xdf51#")])
def test_ra_dec_of_the_zenith_in_both_precisions(high_precision, ra, dec):
    sim = LX200Simulator(SimWorld(clock=SimClock(0.0)), high_precision=high_precision, longitude_deg=0.0,
                         start_utc=J2000)  # the default mount: altitude up to 90°
    sim.altitude.move_to(90.0)
    assert sim.pose_deg() == (0.0, 90.0)  # at time scale 0 the clock jumped to the end of the move…
    sim.set_utc(J2000)  # …so the back door sets the time again
    assert sim.receive(b":GR#") == ra  # at the zenith RA = local sidereal time = GMST at longitude 0
    assert sim.receive(b":GD#") == dec  # and Dec = latitude, 0xDF degree sign
    assert sim.receive(b":GS#") == b"18:41:51#"  # the sidereal time is always HH:MM:SS


def test_the_sky_turns_with_the_simulated_clock(bench):
    wall = FakeWall()
    table, sim, _ = bench(time_scale=10.0, wall=wall, start_utc=J2000)
    ra0, dec0 = sim.equatorial_deg()
    wall.t = 36.0  # 360 simulated seconds
    ra1, dec1 = sim.equatorial_deg()
    assert (ra1 - ra0) % 360.0 == pytest.approx(360.0 * SIDEREAL_RATE_DEG_S, rel=1e-6)  # 1.504°
    assert dec1 == pytest.approx(dec0)  # pointing north on the horizon: on the meridian, Dec holds
    assert sim.utc() == J2000 + timedelta(seconds=360)


def test_site_and_time_getters_answer_in_the_manuals_formats(bench):
    start = datetime(2026, 11, 24, 3, 4, 5, tzinfo=UTC)
    table, sim, _ = bench(connect=False, start_utc=start)
    port = table.port
    replies = {cmd: _query(port, cmd) for cmd in (b":Gc#", b":Gt#", b":Gg#", b":GG#", b":GL#", b":GC#", b":GM#",
                                                   b":GT#", b":GVD#", b":GVT#", b":GVN#", b":GVF#", b":GVP#")}
    assert replies == {b":Gc#": b"24#", b":Gt#": b"+54\xdf51#", b":Gg#": b"-083\xdf06#",  # east negative
                       b":GG#": b"-07#",  # UTC+7: hours added to local time to give UTC
                       b":GL#": b"10:04:05#", b":GC#": b"11/24/26#", b":GM#": b"Bench#", b":GT#": b"60.2#",
                       b":GVD#": b"Nov 21 2025#", b":GVT#": b"12:00:00#", b":GVN#": b"43Eg#",
                       b":GVF#": b"Autostar 43Eg#", b":GVP#": b"Autostar#"}
    assert sim.unknown == []


def test_site_and_time_setters(bench):
    table, sim, _ = bench(connect=False, start_utc=J2000)
    port = table.port
    for command, reply in [(b":St-33*52#", b"1"), (b":Sg289*45#", b"1"), (b":SG-03.5#", b"1"),
                           (b":SL23:15:00#", b"1"), (b":SC02/29/24#", b"1Updating Planetary Data#" + b" " * 32 + b"#"),
                           (b":St+91*00#", b"0"), (b":Sg400*00#", b"0"), (b":SG+25.0#", b"0"), (b":SL24:00:00#", b"0"),
                           (b":SC02/30/24#", b"0"), (b":Stxyz#", b"0"), (b":SL1:2#", b"0")]:
        port.write(command)
        assert port.read_exact(len(reply)) == reply, command
    # Rev L longitude 289°45′ west = 70°15′ east; INDI's signed form is taken too
    assert (sim.latitude_deg, sim.longitude_deg, sim.utc_offset_h) == pytest.approx((-(33 + 52 / 60), 70.25, -3.5))
    assert sim.local_time() == datetime(2024, 2, 29, 23, 15)
    assert sim.utc() == datetime(2024, 2, 29, 19, 45, tzinfo=UTC)  # UTC = local + offset (Rev L's sign)
    port.write(b":Sg-013*24#")
    assert port.read_exact(1) == b"1" and sim.longitude_deg == pytest.approx(13.4)
    port.write(b":SG+00#")  # the offset changes, the local time stays (the module docstring)
    assert port.read_exact(1) == b"1" and sim.local_time() == datetime(2024, 2, 29, 23, 15)
    assert sim.unknown == []


def test_equatorial_goto_slews_to_the_targets_alt_az_now(bench):
    table, sim, world = bench(start_utc=J2000)
    port = table.port
    ra_deg, dec_deg = horizontal_to_equatorial(30.0, 150.0, sim.latitude_deg, sim.sidereal_time_deg())
    ra_text = format_sexagesimal(ra_deg / 15.0, high_precision=True, signed=False, degree_sign=":", seconds_sign=":")
    dec_text = format_sexagesimal(dec_deg, high_precision=True, degree_sign="*", seconds_sign=":")
    assert _query(port, f":Sr{ra_text}#".encode(), 1) == b"1"
    assert _query(port, f":Sd{dec_text}#".encode(), 1) == b"1"
    assert _query(port, b":Gr#") == f"{ra_text}#".encode()
    assert _query(port, b":MS#", 1) == b"0"
    table.wait_until_stopped(timeout_s=2.0)
    # at time scale 0 the sky stands still; the RA target was rounded to 1 s of time (15″ at most)
    assert table.position() == pytest.approx((150.0, 30.0), abs=10 * ARCSEC)
    assert world.stage_true_deg() == pytest.approx((150.0, 30.0), abs=10 * ARCSEC)


def test_equatorial_targets_that_do_not_parse_and_a_goto_without_target_are_refused(bench):
    table, sim, _ = bench(connect=False, start_utc=J2000)
    port = table.port
    assert _query(port, b":MS#") == b"1No Target#"
    for bad in (b":Sr24:00:00#", b":Sr12:60.0#", b":Sr1:2:3#", b":Sd+91*00#", b":Sd+45#"):
        assert _query(port, bad, 1) == b"0", bad
    assert _query(port, b":Sr12:30.5#", 1) == b"1" and sim.target_ra_h == pytest.approx(12.5 + 0.5 / 60)
    assert not (sim.azimuth.busy() or sim.altitude.busy())


@pytest.mark.parametrize("altitude, reply", [(-20.0, b"1Object Below Horizon#"),
                                             (80.0, b"2Object Above Higher Limit#")])
def test_an_equatorial_goto_outside_the_altitude_range_is_refused(altitude, reply):
    # the "horizon" of the bench's mount is its altitude axis's range (the zenith stage goes below 0°)
    sim = LX200Simulator(SimWorld(clock=SimClock(0.0)), AZ_SPEC, AxisSpec(soft_limits_deg=(-10.0, 45.0)),
                         start_utc=J2000)
    ra, dec = horizontal_to_equatorial(altitude, 200.0, sim.latitude_deg, sim.sidereal_time_deg())
    sim.target_ra_h, sim.target_dec_deg = ra / 15.0, dec
    assert sim.receive(b":MS#") == reply
    assert not (sim.azimuth.busy() or sim.altitude.busy())
    assert sim.receive(b":Sa+50*00#:Sa-11*00#") == b"00"  # the same range refuses alt-az targets


@pytest.mark.parametrize("indi_compatible", [False, True])
def test_sa_format_and_ma_reply_follow_the_manual_or_indi(bench, indi_compatible):
    table, sim, _ = bench(connect=False, indi_compatible=indi_compatible)
    port = table.port
    lenient = b"1" if indi_compatible else b"0"  # INDI's %+02d: one digit, a lost sign
    for command, reply in [(b":Sa+05*00#", b"1"), (b":Sa+5*00#", lenient), (b":Sa5*00#", lenient),
                           (b":Sa-5*30#", lenient), (b":Sz045*00#", b"1")]:
        assert _query(port, command, 1) == reply, command
    assert sim.target_altitude_deg == (-5.5 if indi_compatible else 5.0)
    assert _query(port, b":MA#", 1) == (b"1" if indi_compatible else b"0")  # the CONFLICT (module docstring)
    sim.alignment = "L"
    assert _query(port, b":MA#", 1) == (b"0" if indi_compatible else b"1")  # and its fault char


def test_manual_moves_run_at_the_selected_rate_until_stopped(bench):
    wall = FakeWall()
    table, sim, _ = bench(time_scale=1.0, wall=wall, connect=False)
    port = table.port
    port.write(b":RC#:Mn#:Me#")  # centering rate: 0.25 °/s
    wall.t = 4.0
    north = 0.25 * 4.0 - 0.25 ** 2 / 20.0 / 2  # 4 s at 0.25 °/s, less the ramp up at 20 °/s²: 0.9984375°
    assert sim.pose_deg()[1] == pytest.approx(north, abs=1e-6)  # up (north)
    port.write(b":Qn#")  # only the northward move stops, where it is
    wall.t = 8.0
    azimuth, altitude = sim.pose_deg()
    assert altitude == pytest.approx(north, abs=1e-6)
    assert azimuth == pytest.approx(0.25 * 8.0 - 0.25 ** 2 / 20.0 / 2, abs=1e-5)  # east: azimuth increasing
    port.write(b":Qs#")  # halts southward moves only: the east move goes on
    assert sim.azimuth.busy()
    port.write(b":RS#:Ms#")  # max rate (the axis's 10 °/s), down; then :Q# stops everything
    wall.t = 9.0
    port.write(b":Q#")
    assert not (sim.azimuth.busy() or sim.altitude.busy())
    assert sim.pose_deg()[1] == pytest.approx(north - 7.5, abs=1e-6)  # 0.5 s accelerating, 0.5 s at 10 °/s
    assert sim.unknown == []


def test_a_move_into_a_tripped_limit_switch_does_nothing(bench):
    table, sim, _ = bench(connect=False)
    sim.altitude.trip_limit("high")
    table.port.write(b":Mn#")
    assert not sim.altitude.busy()
    table.port.write(b":Ms#")  # off the switch works, down to the fixture's lower hard limit switch
    assert sim.pose_deg()[1] == pytest.approx(-10.0) and sim.altitude.limit_hit == "low"


@pytest.mark.parametrize("indi_compatible", [False, True])
def test_park_and_home_status(bench, indi_compatible):
    wall = FakeWall()
    end = b"#" if indi_compatible else b""  # Rev L: a bare char; INDI reads up to '#'
    table, sim, _ = bench(time_scale=1.0, wall=wall, indi_compatible=indi_compatible, park_deg=(90.0, 10.0))
    port = table.port
    assert _query(port, b":h?#", 1 + len(end)) == b"1" + end  # at power-up (UNCONFIRMED)
    port.write(b":hP#")
    assert _query(port, b":h?#", 1 + len(end)) == b"2" + end
    wall.t = 30.0
    assert _query(port, b":h?#", 1 + len(end)) == b"1" + end
    assert sim.pose_deg() == pytest.approx((90.0, 10.0), abs=ARCSEC)
    table.slew_reply = "auto"  # either mode's :MA# reply
    table.move_to(0.0, 0.0, wait=False)
    wall.t = 60.0
    table.wait_until_stopped(timeout_s=1.0)
    port.write(b":hP#")
    wall.t = 61.0
    port.write(b":Q#")  # a park stopped short
    assert _query(port, b":h?#", 1 + len(end)) == b"0" + end


def test_sim_bench_lx200_section_reaches_the_simulator():
    config = SimBenchConfig(table="lx200", time_scale=0.0,
                            lx200={"indi_compatible": True, "latitude_deg": -31.25, "longitude_deg": 149.0625,
                                   "utc_offset_h": -10.0})
    sim = SimBench(config).devices["table"]
    assert sim.indi_compatible and (sim.latitude_deg, sim.longitude_deg, sim.utc_offset_h) == (-31.25, 149.0625, -10.0)
    assert sim.receive(b":Gt#:Gg#") == b"-31\xdf15#-149\xdf04#"
    assert SimBench(SimBenchConfig(table="lx200")).devices["table"].indi_compatible is False


@pytest.mark.parametrize("indi_compatible, slew_reply", [(False, "manual"), (True, "indi"), (False, "auto"),
                                                         (True, "auto")])
def test_the_driver_reads_the_slew_reply_of_either_mode(bench, indi_compatible, slew_reply):
    table, sim, _ = bench(indi_compatible=indi_compatible)
    table.slew_reply, table.ok_chars = slew_reply, INDI_OK_CHARS if slew_reply == "indi" else OK_CHARS
    table.move_to(33.0, 22.0)
    assert table.position() == pytest.approx((33.0, 22.0), abs=ARCSEC)
    sim.altitude.trip_limit("high")
    with pytest.raises(DeviceFault, match="refused"):
        table.move_to(33.0, 40.0)  # further into the switch: the mount refuses and does not move


def test_a_manual_driver_on_an_indi_compatible_mount_still_catches_a_refusal_at_arrival(bench):
    table, sim, _ = bench(indi_compatible=True)  # the driver reads Rev L: "1" is a fault to it
    with pytest.raises(DeviceFault, match="refused"):
        table.move_to(10.0, 10.0)  # a slew that worked reads as refused: say so loudly rather than guess
    sim.altitude.trip_limit("high")
    with pytest.raises(DeviceFault, match="stopped at"):
        table.move_to(10.0, 20.0)  # INDI's "0" = fault reads as "no fault": the arrival check catches it
