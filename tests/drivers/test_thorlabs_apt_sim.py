"""The APT driver against the K10CR1 simulator through sim:// ports (and once through a pty).

Each test registers a fresh simulator under its own name and unregisters it afterwards.
"""

import itertools
import os
import struct
import time

import pytest

from drivers.errors import DeviceDisconnected, DeviceFault, DeviceTimeout, LimitError, ProtocolError
from drivers.interfaces import Limits
from drivers.sim import registry
from drivers.sim.clock import SimClock
from drivers.sim.motion import AxisSpec, trapezoid
from drivers.sim.pty_bridge import PtyBridge
from drivers.sim.thorlabs_apt import AptStageSimulator
from drivers.sim.world import SimWorld
from drivers.thorlabs_apt import (
    MOVING_MASK,
    AptRotationStage,
    Msg,
    Status,
    header_length,
    move_absolute,
    pack_long,
    pack_short,
    unpack_message,
)

STEP_DEG = 3.0 / 409600.0  # K10CR1 encoder resolution (anchors-protocols §2.4)
_names = itertools.count()


@pytest.fixture
def make_stage():
    """Factory: (world, simulator, driver) for one fresh simulated K10CR1 served at a unique sim:// name."""
    made = []

    def make(time_scale=0.0, spec=AxisSpec(start_true_deg=12.0), timeout_s=0.3, record=None, **sim_kwargs):
        world = SimWorld(clock=SimClock(time_scale))
        sim = AptStageSimulator(world, spec, 55000123, **sim_kwargs)
        world.attach_table(sim.axis, world.new_axis(AxisSpec()))
        name = f"apt-test-{os.getpid()}-{next(_names)}"
        url = registry.register(name, sim)
        made.append(name)
        stage = AptRotationStage.open(url, timeout_s=timeout_s, dwell_s=0.0, record=record,
                                      limits=Limits(-90.0, 90.0))
        stage.poll_s = 0.002
        made.append(stage)
        return world, sim, stage

    yield make
    for item in made:
        if isinstance(item, str):
            registry.unregister(item)
        else:
            item.close()


def test_open_initialises_and_identifies(make_stage):
    _, sim, stage = make_stage()
    assert stage.identify() == "Thorlabs K10CR1 s/n 55000123 fw 3.0.10"
    assert sim.enabled and stage.is_enabled()
    assert not sim.updates, "the init stops volunteered status updates"


@pytest.mark.parametrize("target", [10.0, -33.3333, 0.0001, 89.99])
def test_move_and_read_back_within_encoder_resolution_instant(make_stage, target):
    world, sim, stage = make_stage(time_scale=0.0)
    stage.move_to(target)
    assert abs(stage.position_deg() - target) <= STEP_DEG / 2 + 1e-12
    # the world's true angle followed: the table's zero offset (12°) plus what the controller reads
    assert world.stage_true_deg()[0] == pytest.approx(12.0 + stage.position_deg(), abs=1e-9)
    assert stage.events[-1] == "MOT_MOVE_COMPLETED"


def test_move_in_scaled_simulated_time_takes_the_trapezoid_duration(make_stage):
    world, sim, stage = make_stage(time_scale=20.0)
    stage.set_velocity_params(1.0, 2.0)
    duration = trapezoid(2.0, 1.0, 2.0)  # 2° at 1 °/s, 2 °/s²: 2.5 s simulated, 125 ms wall
    t0, wall0 = world.clock.now(), time.monotonic()
    stage.move_to(2.0, wait=False)
    assert stage.is_moving()
    assert sim.axis.true_deg() < 12.0 + 2.0
    stage.wait_until_stopped(timeout_s=2.0)
    assert world.clock.now() - t0 >= duration
    assert time.monotonic() - wall0 >= duration / 20.0
    assert abs(stage.position_deg() - 2.0) <= STEP_DEG / 2 + 1e-12
    assert sim.axis.true_deg() == pytest.approx(14.0, abs=STEP_DEG)


def test_homing_sets_the_controller_zero_at_the_home_switch(make_stage):
    spec = AxisSpec(start_true_deg=5.0, home_switch_true_deg=1.5, home_position_deg=0.0)
    world, sim, stage = make_stage(spec=spec)
    assert not stage.status().homed
    stage.home()
    assert stage.status().homed
    assert "MOT_MOVE_HOMED" in stage.events
    assert abs(stage.position_deg()) <= STEP_DEG
    assert sim.axis.true_deg() == pytest.approx(1.5, abs=STEP_DEG)
    stage.move_to(20.0)
    assert sim.axis.true_deg() == pytest.approx(21.5, abs=STEP_DEG)


def test_homing_in_scaled_time(make_stage):
    spec = AxisSpec(start_true_deg=0.5, home_switch_true_deg=0.0, home_rate_deg_s=5.0)
    world, sim, stage = make_stage(time_scale=20.0, spec=spec)
    stage.home(wait=False)
    assert stage.status().homing
    stage.wait_until_stopped(timeout_s=2.0)
    assert stage.status().homed and abs(stage.position_deg()) <= STEP_DEG


def test_velocity_parameters_reach_the_axis(make_stage):
    _, sim, stage = make_stage()
    assert stage.velocity_params() == pytest.approx((10.0, 20.0), rel=1e-6)
    stage.set_velocity_params(4.0, 8.0)
    assert stage.velocity_params() == pytest.approx((4.0, 8.0), rel=1e-6)
    assert sim.axis.spec.max_rate_deg_s == pytest.approx(4.0)
    assert sim.axis.spec.accel_deg_s2 == pytest.approx(8.0)


def test_stop_halts_a_long_move_part_way(make_stage):
    world, sim, stage = make_stage(time_scale=20.0)
    stage.set_velocity_params(2.0, 20.0)
    stage.move_to(80.0, wait=False)  # 40 s simulated, 2 s wall
    time.sleep(0.05)
    stage.stop()
    here = stage.wait_until_stopped(timeout_s=1.0)
    assert 0.0 < here < 80.0
    assert not stage.is_moving()
    assert sim.axis.true_deg() == pytest.approx(12.0 + here, abs=STEP_DEG)
    stage.position_deg()  # one more exchange takes in the volunteered MOVE_STOPPED
    assert "MOT_MOVE_STOPPED" in stage.events


def test_stalled_axis_that_still_answers_times_out(make_stage):
    _, sim, stage = make_stage(time_scale=20.0)
    stage.set_velocity_params(2.0, 20.0)
    stage.move_to(60.0, wait=False)  # 30 s simulated, 1.5 s wall: it jams long before the end
    sim.axis.stall()
    with pytest.raises(DeviceTimeout, match="stalled"):
        stage.wait_until_stopped(timeout_s=0.2)
    assert not sim.axis.busy(), "the driver stopped the stalled axis"


def test_stall_in_instant_mode_times_out_too(make_stage):
    _, sim, stage = make_stage(time_scale=0.0)
    sim.axis.stall()
    with pytest.raises(DeviceTimeout):
        stage.move_to(5.0, timeout_s=0.1)


def test_tripped_limit_switch_is_a_device_fault_and_the_axis_can_leave_it(make_stage):
    world, sim, stage = make_stage(time_scale=20.0)
    stage.set_velocity_params(2.0, 20.0)
    stage.move_to(30.0, wait=False)  # 15 s simulated, 0.75 s wall
    time.sleep(0.02)
    sim.axis.trip_limit("high")
    with pytest.raises(DeviceFault, match="forward limit switch"):
        stage.wait_until_stopped(timeout_s=1.0)
    stage.position_deg()
    assert "MOT_MOVE_STOPPED" in stage.events
    with pytest.raises(DeviceFault, match="limit switch"):  # deeper into the switch: refused (HW_RICHRESPONSE)
        stage.move_to(40.0, timeout_s=1.0)
    stage.move_to(-1.0, timeout_s=2.0)  # away from it: allowed
    assert abs(stage.position_deg() + 1.0) <= STEP_DEG


def test_hard_limit_switch_stops_a_move_short(make_stage):
    spec = AxisSpec(start_true_deg=0.0, hard_limits_deg=(-20.0, 20.0))
    _, sim, stage = make_stage(spec=spec)
    with pytest.raises(DeviceFault, match="forward limit switch"):
        stage.move_to(30.0)
    assert stage.position_deg() == pytest.approx(20.0, abs=STEP_DEG)


def test_soft_limit_refusal_sends_nothing(make_stage):
    events = []
    _, sim, stage = make_stage(record=events)
    sent = len(events)
    with pytest.raises(LimitError):
        stage.move_to(95.0)
    assert len(events) == sent
    assert not sim.axis.busy() and sim.axis.position_deg() == 0.0


def test_no_reply_is_a_timeout(make_stage):
    _, sim, stage = make_stage(timeout_s=0.1)
    sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout):
        stage.position_deg()
    sim.faults.clear()
    assert stage.position_deg() == 0.0


@pytest.mark.parametrize("fault", ["garble", "truncate"])
def test_corrupted_reply_is_retried_cleanly_never_a_wrong_reading(make_stage, fault):
    _, sim, stage = make_stage(timeout_s=0.1)
    stage.move_to(45.0)
    setattr(sim.faults, fault, 1)
    assert abs(stage.position_deg() - 45.0) <= STEP_DEG  # one bad reply, one clean retry
    assert stage.retry_count == 1
    setattr(sim.faults, fault, stage.retries + 1)  # bounded: one more bad reply than retries
    with pytest.raises(ProtocolError, match=stage.name) as info:
        stage.position_deg()
    assert info.value.attempts == stage.retries + 1
    assert abs(stage.position_deg() - 45.0) <= STEP_DEG


@pytest.mark.parametrize("updates", [False, True])
@pytest.mark.parametrize("target", [1.0, 5.0, 20.0])
def test_truncated_reply_during_a_move_is_not_a_limit_switch(make_stage, target, updates):
    # the back door cuts the next reply in half: a status reply keeps only its header, and the completion
    # the stage volunteers next must not be decoded as its status word (issue 10 item 5: 60 of 60 before);
    # with status updates on, the cut one may be an update followed by the next
    _, sim, stage = make_stage(time_scale=20.0, timeout_s=0.2, update_period_s=0.01)
    sim.updates = updates
    stage.move_to(target, wait=False)
    for _ in range(3):  # cut the next reply, three times over, while the stage moves and after it stops
        sim.faults.truncate = 1
        t0 = time.monotonic()
        stage.is_moving()
        # one broken attempt (0.2 s) and a good one: a stream of updates must not hold the deadline off
        assert time.monotonic() - t0 < 1.0
    stage.wait_until_stopped(timeout_s=5.0)
    assert abs(stage.position_deg() - target) <= STEP_DEG / 2 + 1e-12
    assert not stage.last_status.faults()


def test_disconnect_is_device_disconnected(make_stage):
    _, sim, stage = make_stage()
    sim.faults.disconnected = True
    with pytest.raises(DeviceDisconnected):
        stage.position_deg()
    with pytest.raises(DeviceDisconnected):
        stage.move_to(10.0)


def test_volunteered_status_updates_do_not_disturb_the_exchanges(make_stage):
    _, sim, stage = make_stage(time_scale=20.0, update_period_s=0.02)
    sim.updates = True  # as after HW_START_UPDATEMSGS
    stage.move_to(3.0, timeout_s=2.0)
    assert abs(stage.position_deg() - 3.0) <= STEP_DEG
    assert stage.last_status is not None


def test_short_form_move_completed_is_understood(make_stage):
    _, sim, stage = make_stage(completion_form="short")
    stage.move_to(7.0)
    stage.position_deg()
    assert stage.events[-1] == "MOT_MOVE_COMPLETED"


def test_the_driver_runs_on_a_pty_where_rts_cannot_be_set():
    world = SimWorld(clock=SimClock(0.0))
    sim = AptStageSimulator(world, AxisSpec(), 55000321)
    with PtyBridge(sim) as bridge:
        stage = AptRotationStage.open(bridge.path, timeout_s=0.5, dwell_s=0.0)
        try:
            assert stage.info().serial == 55000321
            stage.move_to(-12.5)
            assert abs(stage.position_deg() + 12.5) <= STEP_DEG
        finally:
            stage.close()


# -- the simulator's front on its own ---------------------------------------------------------------------------
def _sim(**kwargs):
    world = SimWorld(clock=SimClock(0.0))
    return AptStageSimulator(world, AxisSpec(), 55000123, **kwargs)


def test_simulator_answers_rack_and_bay_addresses_and_ignores_others():
    sim = _sim()
    for dest in (0x50, 0x11, 0x21):
        reply = unpack_message(sim.receive(pack_short(Msg.MOT_REQ_POSCOUNTER, 1, dest=dest)))
        assert (reply.msg_id, reply.dest, reply.source) == (Msg.MOT_GET_POSCOUNTER, 0x01, 0x50)
    assert sim.receive(pack_short(Msg.MOT_REQ_POSCOUNTER, 1, dest=0x22)) == b""


def test_simulator_resyncs_by_dropping_bytes_before_an_unknown_id():
    sim = _sim()
    reply = sim.receive(b"\xff\x00\x13" + pack_short(Msg.MOT_REQ_STATUSBITS, 1))
    assert unpack_message(reply).msg_id == Msg.MOT_GET_STATUSBITS
    assert not sim.inbuf


def test_simulator_waits_for_the_rest_of_a_split_frame():
    sim = _sim()
    frame = bytes.fromhex("53 04 06 00 D0 01 01 00 00 80 BB 00")
    assert sim.receive(frame[:7]) == b""
    assert sim.receive(frame[7:]) == b""
    assert sim.axis.busy() or sim.axis.position_deg() == pytest.approx(90.0)


def test_simulator_volunteers_status_updates_on_the_simulated_clock():
    wall = [0.0]
    world = SimWorld(clock=SimClock(1.0, wall=lambda: wall[0]))
    sim = AptStageSimulator(world, AxisSpec(), 1, update_period_s=0.1)
    assert sim.receive(pack_short(Msg.HW_START_UPDATEMSGS)) == b""
    first = sim.poll()
    assert unpack_message(first).msg_id == Msg.MOT_GET_STATUSUPDATE
    assert sim.poll() == b"", "not again before the period has passed"
    wall[0] = 0.1
    assert unpack_message(sim.poll()).msg_id == Msg.MOT_GET_STATUSUPDATE
    sim.receive(pack_short(Msg.HW_STOP_UPDATEMSGS))
    wall[0] = 1.0
    assert sim.poll() == b""


# -- limit switches, jogs and moves at velocity (frames; the clock is driven by hand) -----------------------------
COUNTS_PER_DEG = 409600.0 / 3.0


class _HandClock:
    """A simulator on a clock that moves only when told: `at(t)` sets the wall time [s] (time scale 1)."""

    def __init__(self, spec=AxisSpec(), **kwargs):
        self.wall = 0.0
        world = SimWorld(clock=SimClock(1.0, wall=lambda: self.wall))
        self.sim = AptStageSimulator(world, spec, 55000123, **kwargs)

    def at(self, t: float) -> "_HandClock":
        self.wall = t
        return self

    def send(self, *frames: bytes) -> list:
        return _frames(self.sim.receive(b"".join(frames)))

    def poll(self) -> list:
        return _frames(self.sim.poll())

    def position_deg(self) -> float:
        return self.sim.position_counts() / COUNTS_PER_DEG


def _frames(stream: bytes) -> list:
    out = []
    while stream:
        size = 6 + header_length(stream[:6])
        out.append(unpack_message(stream[:size]))
        stream = stream[size:]
    return out


def _status(sim) -> int:
    (reply,) = _frames(sim.receive(pack_short(Msg.MOT_REQ_STATUSBITS, 1)))
    return struct.unpack("<HL", reply.data)[1]


def test_limit_switch_parameters_describe_the_axis_and_can_be_set():
    free = _HandClock().sim  # a K10CR1: turns freely, a home switch on the reverse side, no soft limits
    (reply,) = _frames(free.receive(pack_short(Msg.MOT_REQ_LIMSWITCHPARAMS, 1)))
    assert (reply.msg_id, len(reply.data)) == (Msg.MOT_GET_LIMSWITCHPARAMS, 16)
    assert struct.unpack("<HHHllH", reply.data) == (1, 1, 4, 2**31 - 1, -2**31, 1)
    stopped = _HandClock(AxisSpec(hard_limits_deg=(-95.0, 95.0), soft_limits_deg=(-90.0, 90.0))).sim
    (reply,) = _frames(stopped.receive(pack_short(Msg.MOT_REQ_LIMSWITCHPARAMS, 1)))
    assert struct.unpack("<HHHllH", reply.data) == (1, 2, 2, 12288000, -12288000, 2)

    new = struct.pack("<HHHllH", 1, 0x82, 0x83, round(45 * COUNTS_PER_DEG), round(-30 * COUNTS_PER_DEG), 3)
    assert free.receive(pack_long(Msg.MOT_SET_LIMSWITCHPARAMS, new)) == b""
    (reply,) = _frames(free.receive(pack_short(Msg.MOT_REQ_LIMSWITCHPARAMS, 1)))
    assert reply.data == new
    assert free.axis.spec.soft_limits_deg == pytest.approx((-30.0, 45.0))
    refused = _frames(free.receive(move_absolute(round(50 * COUNTS_PER_DEG))))
    assert refused[0].msg_id == Msg.HW_RICHRESPONSE
    free.receive(pack_long(Msg.MOT_SET_LIMSWITCHPARAMS, new[:-2] + struct.pack("<H", 1)))
    assert free.axis.spec.soft_limits_deg is None


def test_move_at_velocity_runs_until_stopped_immediately():
    hand = _HandClock()
    assert hand.send(pack_short(Msg.MOT_MOVE_VELOCITY, 1, 1)) == []
    hand.at(2.0)  # 0.5 s up to 10 °/s, then 1.5 s at it: 17.5°
    assert hand.position_deg() == pytest.approx(17.5, abs=1e-4)
    assert _status(hand.sim) & (Status.MOVING_FORWARD | Status.ACTIVE)
    assert hand.poll() == []
    hand.at(3.0)
    assert hand.position_deg() == pytest.approx(27.5, abs=1e-4)
    # MOVE_STOP and a status request in one write: the reply first, MOVE_STOPPED volunteered after it
    (reply,) = hand.send(pack_short(Msg.MOT_MOVE_STOP, 1, 1), pack_short(Msg.MOT_REQ_STATUSBITS, 1))
    assert reply.msg_id == Msg.MOT_GET_STATUSBITS
    (stopped,) = hand.poll()
    assert stopped.msg_id == Msg.MOT_MOVE_STOPPED
    assert struct.unpack("<HlhHL", stopped.data)[1] == round(27.5 * COUNTS_PER_DEG)
    hand.at(10.0)
    assert hand.position_deg() == pytest.approx(27.5, abs=1e-4) and hand.poll() == []


def test_profiled_stop_runs_on_to_where_deceleration_ends():
    hand = _HandClock()
    hand.send(pack_short(Msg.MOT_MOVE_VELOCITY, 1, 2))  # reverse: counts down
    hand.at(3.0)
    assert hand.send(pack_short(Msg.MOT_MOVE_STOP, 1, 2)) == []
    assert hand.poll() == [], "still braking"
    assert _status(hand.sim) & Status.MOVING_REVERSE
    hand.at(3.0 + 2**0.5 * 10.0 / 20.0 - 0.01)  # the braking move takes √2·v/a (module docstring) …
    assert hand.poll() == []
    hand.at(3.0 + 2**0.5 * 10.0 / 20.0 + 0.06)  # … and the settle time
    (stopped,) = hand.poll()
    assert stopped.msg_id == Msg.MOT_MOVE_STOPPED
    assert hand.position_deg() == pytest.approx(-27.5 - 10.0**2 / (2 * 20.0), abs=1e-4)  # v²/2a further
    assert not _status(hand.sim) & MOVING_MASK


def test_move_at_velocity_stops_on_a_hard_limit_switch():
    hand = _HandClock(AxisSpec(hard_limits_deg=(-20.0, 20.0)))
    hand.send(pack_short(Msg.MOT_MOVE_VELOCITY, 1, 1))
    hand.at(5.0)
    (stopped,) = hand.poll()
    assert stopped.msg_id == Msg.MOT_MOVE_STOPPED
    assert struct.unpack("<HlhHL", stopped.data)[4] & Status.FORWARD_LIMIT
    assert hand.position_deg() == pytest.approx(20.0, abs=STEP_DEG)


def test_jog_step_uses_the_jog_parameters_and_completes():
    hand = _HandClock()
    (jog,) = hand.send(pack_short(Msg.MOT_REQ_JOGPARAMS, 1))
    mode, step, _, _, max_velocity, stop_mode = struct.unpack("<HHllllH", jog.data)[1:]
    assert (mode, stop_mode) == (2, 2) and step == round(COUNTS_PER_DEG)  # 1° single steps
    jog_params = struct.pack("<HHllllH", 1, 2, round(3 * COUNTS_PER_DEG), 0, 30040, max_velocity // 2, 2)
    hand.send(pack_long(Msg.MOT_SET_JOGPARAMS, jog_params))  # 3° at 5 °/s
    hand.send(pack_short(Msg.MOT_MOVE_JOG, 1, 1))
    assert _status(hand.sim) & Status.JOGGING_FORWARD
    duration = trapezoid(3.0, 5.0, 20.0)
    hand.at(duration * 0.9)
    assert hand.poll() == [] and 0.0 < hand.position_deg() < 3.0
    hand.at(duration + 0.06)  # and the settle time
    (done,) = hand.poll()
    assert done.msg_id == Msg.MOT_MOVE_COMPLETED and hand.position_deg() == pytest.approx(3.0, abs=STEP_DEG)
    assert not _status(hand.sim) & MOVING_MASK


def test_continuous_jog_runs_until_stopped_and_direction_sense_is_an_option():
    hand = _HandClock(forward_counts_up=False)
    jog_params = struct.pack("<HHllllH", 1, 1, round(COUNTS_PER_DEG), 0, 30040, 73291090, 2)  # continuous
    hand.send(pack_long(Msg.MOT_SET_JOGPARAMS, jog_params))
    hand.send(pack_short(Msg.MOT_MOVE_JOG, 1, 1))  # forward, which counts down on this stage
    hand.at(2.0)
    assert hand.position_deg() == pytest.approx(-17.5, abs=1e-4)
    assert _status(hand.sim) & Status.JOGGING_FORWARD
    hand.send(pack_short(Msg.MOT_MOVE_STOP, 1, 1))
    assert [m.msg_id for m in hand.poll()] == [Msg.MOT_MOVE_STOPPED]


def test_set_poscounter_rereferences_the_counter_not_the_load():
    hand = _HandClock(AxisSpec(start_true_deg=12.0))
    true = hand.sim.axis.true_deg()
    hand.send(pack_long(Msg.MOT_SET_POSCOUNTER, struct.pack("<Hl", 1, round(5 * COUNTS_PER_DEG))))
    assert hand.position_deg() == pytest.approx(5.0, abs=STEP_DEG)
    assert hand.sim.axis.true_deg() == pytest.approx(true, abs=1e-12)


def test_unknown_message_ids_are_noted_once_per_resync():
    sim = _sim()
    reply = sim.receive(pack_short(0x0427, 1) + pack_short(Msg.MOT_REQ_STATUSBITS, 1))  # REQ_POWERPARAMS
    assert [m.msg_id for m in _frames(reply)] == [Msg.MOT_GET_STATUSBITS]
    assert sim.unknown_ids == [0x0427]
