"""The SMC100 driver against the SMC100 simulator through sim:// ports (anchors-protocols §3.1).

Each test registers a fresh simulator under its own name and unregisters it afterwards.
"""

import itertools
import os
import time

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import Limits
from drivers.newport_smc100 import Smc100Axis, Smc100CommandError
from drivers.sim import registry
from drivers.sim.clock import SimClock
from drivers.sim.motion import AxisSpec, trapezoid
from drivers.sim.newport_smc100 import Smc100Simulator
from drivers.sim.world import SimWorld

STEP_DEG = AxisSpec().step_deg
PRINT_DEG = 5e-7  # replies carry 6 decimals
_names = itertools.count()


@pytest.fixture
def make_axis():
    """Factory: (world, simulator, driver) for one fresh simulated SMC100 at a unique sim:// name."""
    made = []

    def make(time_scale=0.0, spec=AxisSpec(start_true_deg=7.0, home_switch_true_deg=4.0), timeout_s=0.3,
             record=None, home=True):
        world = SimWorld(clock=SimClock(time_scale))
        sim = Smc100Simulator(world, spec)
        world.attach_table(world.new_axis(AxisSpec()), sim.axis)
        name = f"smc100-test-{os.getpid()}-{next(_names)}"
        url = registry.register(name, sim)
        made.append(name)
        axis = Smc100Axis.open(url, timeout_s=timeout_s, record=record, reset_wait_s=0.0,
                               limits=Limits(-90.0, 90.0))
        axis.poll_s = 0.002
        made.append(axis)
        if home:
            axis.home(timeout_s=5.0)
        return world, sim, axis

    yield make
    for item in made:
        if isinstance(item, str):
            registry.unregister(item)
        else:
            item.close()


def test_identify(make_axis):
    _, _, axis = make_axis(home=False)
    assert axis.identify() == "SMC_CC - Controller-driver version 2.0.0; stage URS100BCC_SIM"


def test_move_is_refused_until_homed_then_homing_zeroes_at_the_switch(make_axis):
    world, sim, axis = make_axis(home=False)
    assert axis.state() == "NOT REFERENCED"
    with pytest.raises(Smc100CommandError) as info:
        axis.move_to(10.0)
    assert info.value.code == "H" and "NOT REFERENCED" in info.value.meaning
    axis.home()
    assert axis.state() == "READY"
    assert abs(axis.position_deg()) <= PRINT_DEG
    assert world.stage_true_deg()[1] == pytest.approx(4.0, abs=STEP_DEG)


@pytest.mark.parametrize("target", [10.0, -33.3333, 0.0001, 89.99])
def test_move_and_read_back_within_resolution_instant(make_axis, target):
    world, sim, axis = make_axis()
    axis.move_to(target)
    assert abs(axis.position_deg() - target) <= STEP_DEG / 2 + PRINT_DEG
    assert world.stage_true_deg()[1] == pytest.approx(4.0 + axis.position_deg(), abs=STEP_DEG)
    assert axis.state() == "READY"


def test_move_in_scaled_simulated_time(make_axis):
    world, sim, axis = make_axis(time_scale=20.0, spec=AxisSpec(start_true_deg=0.2))
    t0 = world.clock.now()
    axis.move_to(2.0, wait=False)
    assert axis.is_moving() and axis.state() == "MOVING"
    with pytest.raises(Smc100CommandError) as info:  # no new target while moving
        axis.move_to(3.0, wait=False)
    assert info.value.code == "M"
    axis.wait_until_stopped(timeout_s=2.0)
    assert world.clock.now() - t0 >= trapezoid(2.0, 10.0, 20.0)
    assert abs(axis.position_deg() - 2.0) <= STEP_DEG / 2 + PRINT_DEG
    assert sim.axis.true_deg() == pytest.approx(2.0, abs=STEP_DEG)


def test_homing_again_from_ready_resets_first(make_axis):
    _, sim, axis = make_axis()
    axis.move_to(20.0)
    axis.home()
    assert axis.state() == "READY" and abs(axis.position_deg()) <= PRINT_DEG


def test_stop_halts_a_long_move_part_way(make_axis):
    world, sim, axis = make_axis(time_scale=20.0, spec=AxisSpec(start_true_deg=0.1))
    axis.set_velocity_deg_s(2.0)
    axis.move_to(80.0, wait=False)  # 40 s simulated, 2 s wall
    time.sleep(0.05)
    axis.stop()
    here = axis.wait_until_stopped(timeout_s=1.0)
    assert 0.0 < here < 80.0 and axis.state() == "READY"
    assert sim.axis.true_deg() == pytest.approx(here, abs=STEP_DEG + PRINT_DEG)


def test_stalled_axis_that_still_answers_times_out(make_axis):
    _, sim, axis = make_axis(time_scale=20.0, spec=AxisSpec(start_true_deg=0.1))
    axis.set_velocity_deg_s(2.0)
    axis.move_to(60.0, wait=False)  # 30 s simulated, 1.5 s wall: it jams long before the end
    sim.axis.stall()
    with pytest.raises(DeviceTimeout, match="stalled"):
        axis.wait_until_stopped(timeout_s=0.2)
    assert axis.state() == "READY", "the driver stopped it"


def test_tripped_limit_switch_is_a_device_fault(make_axis):
    _, sim, axis = make_axis(time_scale=20.0, spec=AxisSpec(start_true_deg=0.1))
    axis.set_velocity_deg_s(2.0)
    axis.move_to(30.0, wait=False)  # 15 s simulated, 0.75 s wall
    time.sleep(0.02)
    sim.axis.trip_limit("high")
    with pytest.raises(DeviceFault, match="positive end of run"):
        axis.wait_until_stopped(timeout_s=1.0)


def test_controller_soft_limits_refuse_with_te_g(make_axis):
    _, sim, axis = make_axis(spec=AxisSpec(soft_limits_deg=(-50.0, 50.0)))
    with pytest.raises(Smc100CommandError, match="displacement out of limits") as info:
        axis.move_to(60.0)
    assert info.value.code == "G"
    assert axis.last_error() == "@", "TE clears once read"


def test_bench_soft_limit_refusal_sends_nothing(make_axis):
    events = []
    _, sim, axis = make_axis(record=events)
    sent = len(events)
    with pytest.raises(LimitError):
        axis.move_to(-91.0)
    assert len(events) == sent


def test_velocity_reaches_the_axis(make_axis):
    _, sim, axis = make_axis()
    assert axis.velocity_deg_s() == 10.0
    axis.set_velocity_deg_s(2.5)
    assert axis.velocity_deg_s() == 2.5 and sim.axis.spec.max_rate_deg_s == 2.5


def test_no_reply_is_a_timeout(make_axis):
    _, sim, axis = make_axis(timeout_s=0.1)
    sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout):
        axis.position_deg()


@pytest.mark.parametrize("fault", ["garble", "truncate"])
def test_corrupted_reply_is_retried_cleanly_never_a_wrong_reading(make_axis, fault):
    _, sim, axis = make_axis(timeout_s=0.1)
    axis.move_to(45.0)
    setattr(sim.faults, fault, 1)
    assert abs(axis.position_deg() - 45.0) <= STEP_DEG
    setattr(sim.faults, fault, 2)
    with pytest.raises(ProtocolError):
        axis.position_deg()
    assert abs(axis.position_deg() - 45.0) <= STEP_DEG


def test_disconnect_is_device_disconnected(make_axis):
    _, sim, axis = make_axis()
    sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        axis.position_deg()


# -- the simulator's front on its own ---------------------------------------------------------------------------
def _sim():
    return Smc100Simulator(SimWorld(clock=SimClock(0.0)), AxisSpec())


def test_simulator_ignores_other_addresses_and_flags_unknown_commands():
    sim = _sim()
    assert sim.receive(b"2TP\r\n") == b""
    assert sim.receive(b"1XX\r\n") == b""
    assert sim.receive(b"1TE\r\n") == b"1TEA\r\n"
    assert sim.receive(b"1TE\r\n") == b"1TE@\r\n"


def test_simulator_accepts_queries_with_or_without_question_mark():
    sim = _sim()
    assert sim.receive(b"1TS?\r\n") == sim.receive(b"1TS\r\n") == b"1TS00000A\r\n"
    assert sim.receive(b"1TP?\r\n") == b"1TP0.000000\r\n"


def test_simulator_refusals_follow_the_state():
    wall = [0.0]  # simulated time stands still until the test moves the wall clock
    sim = Smc100Simulator(SimWorld(clock=SimClock(1.0, wall=lambda: wall[0])), AxisSpec(start_true_deg=5.0))
    for line, letter in [(b"1PA1", "H"), (b"1OR", "@"), (b"1OR", "E"), (b"1PA1", "L"), (b"1ST", "@"),
                         (b"1TS", None), (b"1OR", "@")]:
        reply = sim.receive(line + b"\r\n")
        if letter is None:
            assert reply == b"1TS00000B\r\n", "stopped while homing: NOT REFERENCED from homing"
        else:
            assert sim.receive(b"1TE\r\n") == f"1TE{letter}\r\n".encode(), line
    wall[0] = 10.0  # the homing move is over
    assert sim.receive(b"1TS\r\n") == b"1TS000032\r\n"
    for line, letter in [(b"1PAabc", "C"), (b"1OR", "K"), (b"1PA2", "@"), (b"1PA3", "M")]:
        sim.receive(line + b"\r\n")
        assert sim.receive(b"1TE\r\n") == f"1TE{letter}\r\n".encode(), line
