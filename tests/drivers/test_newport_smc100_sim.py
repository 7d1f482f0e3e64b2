"""The SMC100 driver against the SMC100 simulator through sim:// ports (anchors-protocols §3.1).

Each test registers a fresh simulator under its own name and unregisters it afterwards.
"""

import itertools
import os
import time

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import AxisMotion, Limits
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
    _assert_letters(sim, [(b"1PAabc", "C"), (b"1OR", "K"), (b"1PA2", "@"), (b"1PA3", "M")])


def test_expected_motion_reads_velocity_and_acceleration_and_acceleration_shapes_the_move(make_axis):
    world, sim, axis = make_axis(time_scale=20.0, spec=AxisSpec(start_true_deg=0.1))
    assert axis.expected_motion() == AxisMotion(10.0, 20.0)
    axis.set_acceleration_deg_s2(5.0)
    assert axis.expected_motion() == AxisMotion(10.0, 5.0) and sim.axis.spec.accel_deg_s2 == 5.0
    t0 = world.clock.now()
    axis.move_to(10.0, timeout_s=5.0)
    assert world.clock.now() - t0 >= trapezoid(10.0, 10.0, 5.0)  # 2.83 s simulated, against 1.5 s at 20 °/s²
    with pytest.raises(Smc100CommandError) as info:
        axis.set_acceleration_deg_s2(1e12)
    assert info.value.code == "C"


# -- the documented command set, as QMI and pystages send it (research/peer-clients.md) --------------------------
def _ask(sim, line: bytes) -> bytes:
    return sim.receive(line + b"\r\n")


def _te(sim) -> str:
    """The letter TE reports (the reply's framing checked)."""
    reply = _ask(sim, b"1TE")
    assert reply[:3] == b"1TE" and reply[-2:] == b"\r\n", reply
    return reply[3:-2].decode()


def _assert_letters(sim, script) -> None:
    """Send each line of `script`; TE must then report its letter (@: no error)."""
    for line, letter in script:
        _ask(sim, line)
        assert _te(sim) == letter, line


def _ready_sim(time_scale=0.0, wall=None):
    clock = SimClock(time_scale) if wall is None else SimClock(time_scale, wall=lambda: wall[0])
    sim = Smc100Simulator(SimWorld(clock=clock), AxisSpec())
    _ask(sim, b"1OR")
    if wall is not None:
        wall[0] += 1.0
    assert _ask(sim, b"1TS") == b"1TS000032\r\n"
    return sim


def test_empty_lines_blanks_and_lower_case_are_accepted():
    sim = _sim()
    assert sim.receive(b"1TS\r\n\r\n") == b"1TS00000A\r\n"  # QMI's line, with its own CR LF after ours
    assert sim.receive(b"\r\n") == b""
    assert _te(sim) == "@", "an empty line is no error"
    assert _ask(sim, b"1 t p") == b"1TP0.000000\r\n"
    assert _ask(sim, b"1VA 2. 5") == b"" and sim.axis.spec.max_rate_deg_s == 2.5  # the manual's "2P A1.43 6"


def test_tb_gives_the_text_of_a_letter_or_of_the_last_error():
    sim = _sim()
    assert _ask(sim, b"1TBH") == b"1TBH Command not allowed in NOT REFERENCED state\r\n"
    assert _ask(sim, b"1TB@") == b"1TB@ No error\r\n"
    _ask(sim, b"1PA5")  # refused: NOT REFERENCED
    assert _ask(sim, b"1TB") == b"1TBH Command not allowed in NOT REFERENCED state\r\n"
    assert _te(sim) == "@", "TB without a letter read the error"
    assert _ask(sim, b"1TBZ") == b"" and _te(sim) == "C"


def test_configuration_state_holds_the_parameters_and_sa_takes_effect_on_leaving_it():
    sim = _sim()
    assert _ask(sim, b"1PW?") == b"1PW0\r\n"
    _ask(sim, b"1PW1")
    assert _ask(sim, b"1TS") == b"1TS000014\r\n" and _ask(sim, b"1PW?") == b"1PW1\r\n"
    _assert_letters(sim, [(b"1OR", "I"), (b"1PA1", "I"), (b"1BA0.01", "@"), (b"1BH0.02", "D"), (b"1BA0", "@"),
                          (b"1BH0.02", "@"), (b"1OT20", "@"), (b"1OT1", "C"), (b"1JR0.1", "@"), (b"1AC50", "@"),
                          (b"1SA1", "C"), (b"1SA7", "@")])
    assert [_ask(sim, q) for q in (b"1BA?", b"1BH?", b"1OT?", b"1JR?", b"1AC?", b"1SA?")] == [
        b"1BA0.000000\r\n", b"1BH0.020000\r\n", b"1OT20.000000\r\n", b"1JR0.100000\r\n", b"1AC50.000000\r\n",
        b"1SA7\r\n"]
    _ask(sim, b"1PW0")
    assert _ask(sim, b"1TS") == b"", "the controller now answers address 7"
    assert _ask(sim, b"7TS") == b"7TS00000C\r\n"  # NOT REFERENCED from CONFIGURATION
    assert _ask(sim, b"7PW?") == b"7PW0\r\n"


def test_configuration_only_parameters_are_refused_elsewhere():
    sim = _ready_sim()
    _assert_letters(sim, [(line, "K") for line in (b"1BA0.1", b"1BH0.1", b"1OT5", b"1SA3", b"1PW1")])
    assert _ask(sim, b"1PW0") == b"" and _te(sim) == "K"


def test_disable_state_mm0_and_mm1():
    sim = _ready_sim()
    assert _ask(sim, b"1MM?") == b"1MM1\r\n"
    _ask(sim, b"1MM0")
    assert _ask(sim, b"1TS") == b"1TS00003C\r\n" and _ask(sim, b"1MM?") == b"1MM0\r\n"
    _assert_letters(sim, [(b"1PA5", "J"), (b"1OR", "J"), (b"1MM0", "@"), (b"1MM1", "@"), (b"1MM1", "@"),
                          (b"1MM2", "C")])
    assert _ask(sim, b"1TS") == b"1TS000034\r\n"  # READY from DISABLE
    _ask(sim, b"1RS")
    _ask(sim, b"1MM0")
    assert _te(sim) == "H"


def test_mm0_while_moving_stops_in_disable():
    wall = [0.0]
    sim = _ready_sim(time_scale=1.0, wall=wall)
    _ask(sim, b"1PA100")
    wall[0] += 2.0
    _ask(sim, b"1MM0")
    assert _ask(sim, b"1TS") == b"1TS00003D\r\n"  # DISABLE from MOVING
    here = sim.axis.position_deg()
    wall[0] += 20.0
    assert 0.0 < here < 100.0 and sim.axis.position_deg() == here


def test_pt_is_the_time_of_a_relative_move_at_the_present_speeds():
    sim = _sim()
    assert _ask(sim, b"1PT10") == b"1PT1.500000\r\n"  # 10° at 10 °/s, 20 °/s²
    assert _ask(sim, b"1PT-10") == b"1PT1.500000\r\n"
    _ask(sim, b"1VA5")
    assert _ask(sim, b"1PT10") == f"1PT{trapezoid(10.0, 5.0, 20.0):.6f}\r\n".encode()
    assert _ask(sim, b"1PT") == b"" and _te(sim) == "C"


def test_parameters_cannot_change_while_moving():
    wall = [0.0]
    sim = _ready_sim(time_scale=1.0, wall=wall)
    _ask(sim, b"1PA50")
    _assert_letters(sim, [(line, "M") for line in (b"1VA2", b"1AC2", b"1JR1")])
    assert _ask(sim, b"1AC?") == b"1AC20.000000\r\n"  # queries are answered in every state


def test_address_less_st_and_mm_are_broadcast_and_other_commands_need_an_address():
    wall = [0.0]
    sim = _ready_sim(time_scale=1.0, wall=wall)
    _ask(sim, b"1PA100")
    wall[0] += 2.0
    assert _ask(sim, b"ST") == b""  # pystages' stop()
    assert _ask(sim, b"1TS") == b"1TS000033\r\n"
    assert _ask(sim, b"MM0") == b"" and _ask(sim, b"1TS") == b"1TS00003C\r\n"
    assert _ask(sim, b"MM1") == b"" and _ask(sim, b"1TS") == b"1TS000034\r\n"  # pystages before every move
    assert _ask(sim, b"0MM0") == b"" and _ask(sim, b"1TS") == b"1TS00003C\r\n"  # pymeasure's address 0
    assert _te(sim) == "@"
    assert _ask(sim, b"TS") == b"" and _te(sim) == "B"
    assert _ask(sim, b"0TS") == b"" and _te(sim) == "@", "address 0 is no controller's for a query"


def test_sa_query_answers_the_address():
    sim = Smc100Simulator(SimWorld(clock=SimClock(0.0)), AxisSpec(), address=3)
    assert _ask(sim, b"3SA?") == b"3SA3\r\n"  # pystages' controller_address()
