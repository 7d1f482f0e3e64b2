"""The simulated world's physics: axis motion, lamp, and the sun direction the table sets."""

import pytest

from calibration.geometry import incidence_from_stage_angle
from drivers.sim.clock import SimClock
from drivers.sim.lamp import LED, XENON, LampModel
from drivers.sim.motion import AxisLimitError, AxisModel, AxisSpec, trapezoid
from drivers.sim.world import SimWorld


class FakeWall:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_trapezoid_and_triangle_durations():
    assert trapezoid(90.0, 10.0, 20.0) == pytest.approx(90 / 10 + 10 / 20)
    assert trapezoid(1.0, 10.0, 20.0) == pytest.approx(2 * (1 / 20) ** 0.5)
    assert trapezoid(0.0, 10.0, 20.0) == 0.0


def test_a_move_takes_simulated_time_and_passes_through_the_profile():
    wall = FakeWall()
    clock = SimClock(1.0, wall=wall)
    axis = AxisModel(AxisSpec(max_rate_deg_s=10, accel_deg_s2=20, settle_s=0.1, step_deg=1e-4), clock)
    duration = axis.move_to(30.0)
    assert duration == pytest.approx(3.5)
    wall.t += 0.25  # still accelerating: s = a t² / 2
    assert axis.position_deg() == pytest.approx(0.625, abs=1e-4) and axis.busy()
    wall.t += 3.25
    assert axis.position_deg() == pytest.approx(30.0) and axis.busy()  # settling
    wall.t += 0.1 + 1e-9
    assert not axis.busy()


def test_time_scale_and_instant_mode():
    wall = FakeWall()
    fast = AxisModel(AxisSpec(max_rate_deg_s=10, accel_deg_s2=20, settle_s=0.0), SimClock(10.0, wall=wall))
    fast.move_to(30.0)
    wall.t += 0.35 + 1e-9  # 3.5 s of simulated time
    assert not fast.busy()
    clock = SimClock(0.0)
    axis = AxisModel(AxisSpec(settle_s=0.2), clock)
    axis.move_to(45.0)
    assert not axis.busy() and axis.position_deg() == pytest.approx(45.0)
    assert clock.now() == pytest.approx(trapezoid(45.0, 10, 20) + 0.2)


def test_encoder_steps_backlash_and_zero_offset():
    clock = SimClock(0.0)
    spec = AxisSpec(step_deg=0.01, backlash_deg=0.02, start_true_deg=1.0, home_switch_true_deg=0.05)
    axis = AxisModel(spec, clock)
    axis.move_to(10.004)
    assert axis.position_deg() == pytest.approx(10.0)  # quantised to the step
    axis.home()
    assert axis.homed and axis.position_deg() == pytest.approx(0.0)
    axis.move_to(20.0)
    up = axis.true_deg()
    axis.move_to(30.0)
    axis.move_to(20.0)
    down = axis.true_deg()
    assert up - down == pytest.approx(-0.02)  # the load lags the motor by the backlash
    assert (up + down) / 2 == pytest.approx(20.0 + 0.05, abs=0.006)  # zero offset = home switch truth


def test_soft_and_hard_limits():
    axis = AxisModel(AxisSpec(soft_limits_deg=(-10, 100), hard_limits_deg=(-20, 90)), SimClock(0.0))
    with pytest.raises(AxisLimitError):
        axis.move_to(120.0)
    axis.move_to(95.0)  # allowed by the controller, stopped by the switch
    assert axis.limit_hit == "high" and axis.position_deg() == pytest.approx(90.0, abs=1e-4)
    with pytest.raises(AxisLimitError, match="limit switch"):
        axis.move_to(99.0)
    axis.move_to(45.0)  # backing off the switch is allowed
    assert axis.limit_hit is None


def test_stall_freezes_the_axis_while_it_reports_a_move():
    wall = FakeWall()
    axis = AxisModel(AxisSpec(), SimClock(1.0, wall=wall))
    axis.move_to(40.0)
    wall.t += 1.0
    axis.stall()
    frozen = axis.position_deg()
    wall.t += 100.0
    assert axis.busy() and axis.position_deg() == frozen
    axis.stop()
    assert not axis.busy()
    axis.move_to(50.0)
    wall.t += 100.0
    assert axis.position_deg() == frozen  # still jammed
    axis.unstall()
    axis.move_to(50.0)
    wall.t += 100.0
    assert axis.position_deg() == pytest.approx(50.0)


def test_xenon_warm_up_drift_shutter_and_fault():
    wall = FakeWall()
    lamp = LampModel(XENON, SimClock(1.0, wall=wall))
    lamp.start()
    assert lamp.relative_output() == 0.0  # igniting
    wall.t += XENON.ignition_s + 1.0
    assert 0.69 < lamp.relative_output() < 0.72 and not lamp.is_warm()
    wall.t = 100.0 + lamp.warm_at() + 1.0  # the fake wall started at 100 s
    assert lamp.is_warm() and lamp.relative_output() == pytest.approx(1.0, abs=0.015)
    assert lamp.irradiance() == 0.0
    lamp.shutter_open = True
    assert lamp.irradiance() == pytest.approx(lamp.relative_output())
    lamp.inject_fault()
    assert lamp.irradiance() == 0.0 and not lamp.is_warm()
    lamp.start()
    assert not lamp.on  # a faulted supply does not strike


def test_led_is_at_once_and_instant_mode_skips_the_warm_up():
    lamp = LampModel(LED, SimClock(0.0))
    lamp.start()
    assert lamp.is_warm()
    xenon = LampModel(XENON, SimClock(0.0))
    xenon.start()
    assert xenon.is_warm() and xenon.clock.now() == pytest.approx(xenon.warm_at())


@pytest.mark.parametrize("source_mm", [710.0, 7100.0])
def test_world_sun_direction_follows_the_table_through_eq8(source_mm):
    from calibration.design import BenchGeometry
    world = SimWorld(bench=BenchGeometry(source_distance_mm=source_mm))
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    world.azimuth.move_to(135.0)
    world.zenith.move_to(40.0)
    zenith, azimuth = world.sun_direction_body()
    assert zenith == pytest.approx(incidence_from_stage_angle(40.0, 136.2, source_mm), abs=1e-3)
    assert azimuth == pytest.approx(135.0, abs=1e-3)
    world.zenith.move_to(-20.0)
    zenith, azimuth = world.sun_direction_body()
    assert zenith == pytest.approx(abs(incidence_from_stage_angle(-20.0, 136.2, source_mm)), abs=1e-3)
    assert azimuth == pytest.approx(315.0, abs=1e-3)


def test_mount_misalignment_tilts_the_body_frame():
    world = SimWorld(mount_tilt_x_deg=0.5)
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    zenith, azimuth = world.sun_direction_body()
    assert zenith == pytest.approx(0.5, abs=1e-6) and azimuth == pytest.approx(180.0, abs=1e-6)


def test_alt_az_axis_order_gives_the_gimbal_direction():
    from calibration.design import BenchGeometry
    world = SimWorld(bench=BenchGeometry(lever_arm_mm=0.0, source_distance_mm=1e9), axis_order="zenith-on-azimuth")
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    world.azimuth.move_to(30.0)
    zenith, azimuth = world.sun_direction_body()
    assert zenith == pytest.approx(30.0, abs=1e-5) and azimuth == pytest.approx(0.0, abs=1e-5)
    world.azimuth.move_to(0.0)
    world.zenith.move_to(20.0)
    zenith, azimuth = world.sun_direction_body()
    assert zenith == pytest.approx(20.0, abs=1e-5) and azimuth == pytest.approx(90.0, abs=1e-5)
    world.azimuth.move_to(30.0)
    zenith, _ = world.sun_direction_body()
    import math
    assert math.cos(math.radians(zenith)) == pytest.approx(math.cos(math.radians(30)) * math.cos(math.radians(20)),
                                                           abs=1e-6)
    with pytest.raises(ValueError, match="axis_order"):
        SimWorld(axis_order="sideways")


def test_a_move_that_supersedes_homing_does_not_rezero_the_axis():
    wall = FakeWall()
    axis = AxisModel(AxisSpec(start_true_deg=-20.0, home_switch_true_deg=0.0), SimClock(1.0, wall=wall))
    axis.home()
    wall.t += 0.5
    axis.move_to(30.0)  # the operator changes their mind mid-homing
    wall.t += 60.0
    assert not axis.homed and axis.position_deg() == pytest.approx(30.0)
    axis.home()
    wall.t += 60.0
    axis.stop()  # a homing that ended unobserved still re-zeroes
    assert axis.homed and axis.position_deg() == pytest.approx(0.0)
