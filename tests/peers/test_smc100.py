"""Other people's SMC100 clients against the simulated SMC100 (research/peer-clients.md): pystages'
``SMC100`` over a pty (drivers/sim/pty_bridge.py), QMI's ``Newport_SMC100CC`` over TCP, each in a venv of its
own (scripts/setup-peers.sh). Each runs an ordinary session against a simulator served in this process —
connect, read state and position, home, move absolute and relative, stop — and the test checks the simulated
axis itself moved. The simulated clock runs 10× fast, so a move takes real time and the clients see MOVING.

No exchange may wait on a timeout: every call that does not wait for motion is timed in the client and must
take a small fraction of the client's own timeout (pystages reads without a timeout: an unanswered query
hangs it, which run_peer's limit turns into a failure)."""

from __future__ import annotations

import pytest
from peers.peer import host_port, run_peer, served, slow_calls

from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.motion import trapezoid
from drivers.sim.newport_smc100 import DISABLE_FROM_READY, READY_FROM_MOVING
from drivers.sim.pty_bridge import PtyBridge

TIME_SCALE = 10.0
PRINT_DEG = 2e-5  # a step of the encoder (3°/409600) and the printed decimals
CALL_LIMIT_S = 0.5  # the longest a call that does not wait for motion may take
QMI_TIMEOUT_S = 5.0  # Newport_SingleAxisMotionController.DEFAULT_RESPONSE_TIMEOUT


@pytest.fixture
def bench():
    """The simulated bench with an SMC100 table; the tests drive its azimuth controller."""
    return SimBench(SimBenchConfig(table="smc100", time_scale=TIME_SCALE))


PYSTAGES_SESSION = """
import time
from pystages.smc100 import SMC100
from pystages.vector import Vector


def wait(stage):
    # wait_move_finished() polls the same way; counting the polls that saw motion shows the move took time
    moving_polls, t0 = 0, time.monotonic()
    while stage.is_moving:
        moving_polls += 1
    return moving_polls, time.monotonic() - t0

out = {}
stage = timed("connect", SMC100, ARGS["path"], [1])  # asks 1TS?
state = timed("state", stage.get_error_and_state, 1)
out["state0"], out["errors0"] = int(state.state), int(state.error)
out["address"] = timed("address", stage.controller_address, 1)  # 1SA?
timed("home", stage.home, False)
out["home_polls"], _ = wait(stage)
out["homed_state"] = int(stage.get_error_and_state(1).state)
out["position0"] = timed("position", lambda: stage.position.x)

def go(value):
    stage.position = Vector(value)  # address-less MM1, then 1PA
timed("absolute", go, 30.0)
out["absolute_polls"], out["absolute_s"] = wait(stage)
out["position1"] = stage.position.x
timed("relative", stage.move_relative, 1, -5.0)  # address-less MM1, then 1PR
out["relative_polls"], _ = wait(stage)
out["position2"] = stage.position.x

timed("long", stage.set_position, 1, 300.0, False)
time.sleep(0.3)
out["moving_before_stop"] = stage.is_moving
timed("stop", stage.stop)  # address-less ST
out["moving_after_stop"] = stage.is_moving
out["position3"] = stage.position.x

timed("disable", stage.enter_leave_disable_state, 1, True)  # 1MM0
out["disabled"] = stage.is_disabled
out["disabled_state"] = int(stage.get_error_and_state(1).state)
timed("enable_and_go", go, 10.0)  # the address-less MM1 leaves DISABLE before the move
out["enabled_polls"], _ = wait(stage)
out["position4"] = stage.position.x
timed("stop_addressed", stage.stop, 1)  # 1ST while READY: nothing to stop
out["final_state"] = int(stage.get_error_and_state(1).state)
out["calls"] = calls
print(json.dumps(out))
"""


def test_pystages_over_a_pty(bench):
    sim = bench.devices["table-azimuth"]
    with PtyBridge(sim) as bridge:
        out = run_peer("pystages", PYSTAGES_SESSION, timeout_s=30.0, path=bridge.path)

    assert out["state0"] == 0x0A and out["errors0"] == 0  # NOT REFERENCED from reset, no positioner error
    assert out["address"] == 1  # 1SA? answered (it used to be retried forever)
    assert out["homed_state"] == 0x32 and abs(out["position0"]) <= PRINT_DEG

    assert out["absolute_polls"] > 0, "the client saw the axis MOVING"
    assert out["absolute_s"] >= trapezoid(30.0, 10.0, 20.0) / TIME_SCALE * 0.9  # the move took its time
    assert out["position1"] == pytest.approx(30.0, abs=PRINT_DEG)
    assert out["relative_polls"] > 0 and out["position2"] == pytest.approx(25.0, abs=PRINT_DEG)

    assert out["moving_before_stop"] and not out["moving_after_stop"]  # the address-less ST stopped it
    assert 25.0 < out["position3"] < 300.0

    assert out["disabled"] and out["disabled_state"] == DISABLE_FROM_READY
    assert out["enabled_polls"] > 0 and out["position4"] == pytest.approx(10.0, abs=PRINT_DEG)
    assert out["final_state"] == READY_FROM_MOVING

    # the simulated axis is where the client says, and the session left no command error behind
    assert sim.axis.position_deg() == pytest.approx(out["position4"], abs=PRINT_DEG)
    offset = bench.config.azimuth_axis.home_switch_true_deg  # the table's zero offset
    assert sim.axis.true_deg() == pytest.approx(10.0 + offset, abs=PRINT_DEG)
    assert sim.error == "@"
    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited: {slow}"


QMI_SESSION = """
import time
import qmi
from qmi.core.exceptions import QMI_InstrumentException
from qmi.instruments.newport.actuators import LinearActuator
from qmi.instruments.newport.smc_100cc import Newport_SMC100CC

# fixed sleeps for a real controller's execution time (0.5 s after every TE, 10 s after PW0), not timeouts:
# the simulator executes at once, and without them a reply that never comes shows as QMI's 5 s timeout
Newport_SMC100CC.COMMAND_EXEC_TIME = 0.0
Newport_SMC100CC.PW0_EXEC_TIME = 0.0


def wait(smc):
    moving_polls = 0
    while True:
        _, state = smc.get_positioner_error_and_state()
        if not state.startswith(("MOVING", "HOMING")):
            return moving_polls, state
        moving_polls += 1

qmi.start("peer_smc100", config_file=None, init_logging=False)
try:
    rotation = LinearActuator(-360.0, 360.0, 20.0, 1e-6, 1e-4, 0.0, 1e-5)  # a rotation stage in degrees
    smc = qmi.make_instrument("smc", Newport_SMC100CC, ARGS["transport"], "SIM", {1: rotation})
    out = {}
    timed("open", smc.open)
    out["idn"] = list(timed("idn", smc.get_idn))
    out["state0"] = list(timed("state", smc.get_positioner_error_and_state))
    out["error"] = list(timed("error", smc.get_error))
    out["acceleration"] = timed("acceleration", smc.get_acceleration)
    out["velocity"] = timed("velocity", smc.get_velocity)
    out["jerk"] = timed("jerk", smc.get_jerk_time)
    out["home_timeout"] = timed("home_timeout", smc.get_home_search_timeout)
    out["motion_time"] = timed("motion_time", smc.get_motion_time, 10.0)
    # these enter CONFIGURATION (PW1), ask, and leave it (PW0)
    out["backlash"] = timed("backlash", smc.get_backlash_compensation)
    out["hysteresis"] = timed("hysteresis", smc.get_hysteresis_compensation)
    out["address"] = timed("address", smc.get_controller_rs485_address)
    out["stage"] = timed("stage", smc.get_stage_identifier)
    out["configured_state"] = timed("state2", smc.get_positioner_error_and_state)[1]

    timed("home", smc.home_search)
    out["home_polls"], out["homed_state"] = wait(smc)
    try:
        smc.home_search()  # OR in READY: refused, QMI reads TE then TB
        out["refusal"] = None
    except QMI_InstrumentException as exc:
        out["refusal"] = str(exc)
    timed("absolute", smc.move_absolute, 30.0)
    out["absolute_polls"], _ = wait(smc)
    out["position1"] = timed("position", smc.get_position)
    timed("relative", smc.move_relative, -5.0)
    out["relative_polls"], _ = wait(smc)
    out["position2"] = smc.get_position()
    out["setpoint"] = timed("setpoint", smc.get_setpoint)

    timed("long", smc.move_absolute, 300.0)
    time.sleep(0.3)
    out["state_before_stop"] = smc.get_positioner_error_and_state()[1]
    timed("stop", smc.stop_motion)
    out["state_after_stop"] = smc.get_positioner_error_and_state()[1]
    out["position3"] = smc.get_position()

    timed("disable_false", smc.set_disable_state, False)  # QMI sends MM0
    out["state_mm0"] = smc.get_positioner_error_and_state()[1]
    out["qmi_reads_disabled"] = timed("is_disabled", smc.is_in_disable_state)
    timed("disable_true", smc.set_disable_state, True)  # QMI sends MM1
    out["state_mm1"] = smc.get_positioner_error_and_state()[1]
    out["final_error"] = list(smc.get_error())
    timed("close", smc.close)
    out["calls"] = calls
finally:
    qmi.stop()
print(json.dumps(out))
"""


def test_qmi_over_tcp(bench):
    sim = bench.devices["table-azimuth"]
    with served(bench) as server:
        host, port = host_port(server.urls["table-azimuth"])
        out = run_peer("qmi", QMI_SESSION, timeout_s=60.0, transport=f"tcp:{host}:{port}")

    assert out["idn"][:2] == ["Newport", "SMC_CC"]
    assert out["state0"] == [[], "NOT REFERENCED from RESET"]
    assert out["error"] == ["@", "No error"]
    assert (out["acceleration"], out["velocity"]) == (20.0, 10.0)
    assert out["jerk"] == sim.jerk_time_s and out["home_timeout"] == sim.home_timeout_s
    assert out["motion_time"] == pytest.approx(trapezoid(10.0, 10.0, 20.0), abs=1e-6)
    assert (out["backlash"], out["hysteresis"], out["address"]) == (0.0, 0.0, 1)
    assert out["stage"].endswith(sim.stage_id)
    assert out["configured_state"] == "NOT REFERENCED from CONFIGURATION."  # PW0 left CONFIGURATION

    assert out["homed_state"] == "READY from HOMING."
    assert out["refusal"] == "Error K: Command not allowed in READY state"  # TE, then TB's text
    assert out["absolute_polls"] > 0 and out["position1"] == pytest.approx(30.0, abs=PRINT_DEG)
    assert out["relative_polls"] > 0 and out["position2"] == pytest.approx(25.0, abs=PRINT_DEG)
    assert out["setpoint"] == pytest.approx(25.0, abs=PRINT_DEG)
    assert out["state_before_stop"] == "MOVING." and out["state_after_stop"] == "READY from MOVING."
    assert 25.0 < out["position3"] < 300.0
    assert sim.axis.position_deg() == pytest.approx(out["position3"], abs=PRINT_DEG)  # the axis stopped there

    # CONFLICT (anchors-protocols §3.1): QMI's set_disable_state(False) sends MM0, which the manual's majority
    # reading (and the simulator) takes as "enter DISABLE"; QMI then reads MM? = 0 as "not disabled"
    assert out["state_mm0"] == "DISABLE from READY." and out["qmi_reads_disabled"] is False
    assert out["state_mm1"] == "READY from DISABLE."
    assert out["final_error"] == ["@", "No error"]
    slow = slow_calls(out, CALL_LIMIT_S)
    assert not slow, f"calls that waited (QMI's own timeout is {QMI_TIMEOUT_S} s): {slow}"
