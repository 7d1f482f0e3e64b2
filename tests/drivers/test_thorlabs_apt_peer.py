"""Acceptance: a peer written by someone else — PyPI's ``thorlabs-apt-device`` — drives the simulated K10CR1.

If that package moves the simulated stage and reads its position back, the simulator's wire format is the
APT protocol as others implement it, not only as our driver reads it.

How the package opens its port (read in ``thorlabs_apt_device/devices/aptdevice.py``, 0.3.8): it calls
``serial.Serial(serial_port, baudrate=115200, …, timeout=0.1)`` itself, so it cannot take a ``sim://``
URL; it needs a path. The simulator is therefore served on a pseudo-terminal by
:class:`drivers.sim.pty_bridge.PtyBridge`. The package does not cycle RTS and does not ask for RTS/CTS,
and pyserial's own ``open()`` ignores the ENOTTY of the RTS/DTR ioctls on a pty, so no patch of its port
opening is needed.

0.3.8 has no K10CR1 class; its generic ``APTDevice_Motor`` addressed to the USB unit (0x50), channel 1,
is how a K10CR1 is driven with it. Positions are in counts (409600/3 per degree, anchors-protocols §2.4).
"""

import time

import pytest

thorlabs_apt_device = pytest.importorskip("thorlabs_apt_device")

from drivers.sim.clock import SimClock  # noqa: E402
from drivers.sim.motion import AxisSpec  # noqa: E402
from drivers.sim.pty_bridge import PtyBridge  # noqa: E402
from drivers.sim.thorlabs_apt import AptStageSimulator  # noqa: E402
from drivers.sim.world import SimWorld  # noqa: E402

COUNTS_PER_DEG = 409600 / 3
ONE_COUNT_DEG = 1 / COUNTS_PER_DEG


def _wait(predicate, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return False


@pytest.fixture
def peer_bench(recwarn):
    """A simulated K10CR1 on a pty, and a factory for the package's device object on it."""
    world = SimWorld(clock=SimClock(20.0))
    sim = AptStageSimulator(world, AxisSpec(start_true_deg=3.0, home_switch_true_deg=2.0), 55000123)
    world.attach_table(sim.axis, world.new_axis(AxisSpec()))
    devices = []
    with PtyBridge(sim) as bridge:

        def connect(status_updates):
            device = thorlabs_apt_device.APTDevice_Motor(
                serial_port=bridge.path, home=False, status_updates=status_updates,
                controller=thorlabs_apt_device.EndPoint.USB, bays=(thorlabs_apt_device.EndPoint.USB,),
                channels=(1,))
            devices.append(device)
            return device

        yield world, sim, connect
        for device in devices:
            device.close()
        # the package says goodbye (HW_DISCONNECT) from its own thread; let it finish before the pty goes
        assert _wait(lambda: sim.host_disconnected, 2.0)
    # the package's decoder warns on every frame it cannot parse: there must be none
    assert not [w for w in recwarn if "message" in str(w.message).lower()], [str(w.message) for w in recwarn]


def test_peer_package_moves_the_simulated_stage_and_reads_the_position_back(peer_bench):
    world, sim, connect = peer_bench
    stage = connect("polled")  # the package polls MOT_REQ_STATUSUPDATE (0x0480) every 10 ms
    status = stage.status_[0][0]
    true_before = sim.axis.true_deg()

    stage.move_absolute(position=round(10.0 * COUNTS_PER_DEG))
    assert _wait(lambda: status["msg"] == "mot_get_statusupdate" and not status["moving_forward"]
                 and abs(status["position"] / COUNTS_PER_DEG - 10.0) <= ONE_COUNT_DEG)

    assert abs(status["position"] / COUNTS_PER_DEG - 10.0) <= ONE_COUNT_DEG / 2
    assert sim.axis.true_deg() - true_before == pytest.approx(10.0, abs=ONE_COUNT_DEG)
    assert world.stage_true_deg()[0] == pytest.approx(13.0, abs=ONE_COUNT_DEG)
    # what the package learnt of the velocity parameters, in K10CR1 units (anchors-protocols §2.4)
    assert stage.velparams_[0][0]["max_velocity"] == 73291090
    assert stage.velparams_[0][0]["acceleration"] == 30040


def test_peer_package_homes_the_stage(peer_bench):
    world, sim, connect = peer_bench
    stage = connect("polled")
    status = stage.status_[0][0]
    stage.home()
    assert _wait(lambda: status["homed"] and not status["homing"])
    assert status["position"] == 0
    assert sim.axis.true_deg() == pytest.approx(2.0, abs=ONE_COUNT_DEG)


def test_peer_package_learns_the_position_from_the_volunteered_move_completed(peer_bench):
    world, sim, connect = peer_bench
    stage = connect("none")  # no polling: only MOVE_COMPLETED (long form) updates its status
    status = stage.status_[0][0]
    stage.move_absolute(position=round(-4.0 * COUNTS_PER_DEG))
    assert _wait(lambda: status["msg"] == "mot_move_completed")
    assert abs(status["position"] / COUNTS_PER_DEG + 4.0) <= ONE_COUNT_DEG / 2
    assert sim.axis.true_deg() == pytest.approx(3.0 - 4.0, abs=ONE_COUNT_DEG)


def test_peer_package_receives_status_updates_after_start_updatemsgs(peer_bench):
    world, sim, connect = peer_bench
    # The package reads until the line stays quiet for its 0.1 s timeout before it writes anything: a
    # stream faster than that (0.1 s simulated = 5 ms wall at time scale 20) would starve its writer.
    sim.update_period_s = 4.0  # 0.2 s wall
    stage = connect("auto")  # sends HW_START_UPDATEMSGS, then keep-alives
    status = stage.status_[0][0]
    assert _wait(lambda: sim.updates and status["msg"] == "mot_get_statusupdate")
    stage.move_absolute(position=round(2.5 * COUNTS_PER_DEG))
    assert _wait(lambda: not status["moving_forward"]
                 and abs(status["position"] / COUNTS_PER_DEG - 2.5) <= ONE_COUNT_DEG)


def test_peer_package_moves_at_velocity_until_stopped(peer_bench):
    world, sim, connect = peer_bench
    stage = connect("polled")
    status = stage.status_[0][0]
    stage.move_velocity("forward")  # MOT_MOVE_VELOCITY, direction 1: counts up (sim default)
    assert _wait(lambda: status["moving_forward"] and status["position"] / COUNTS_PER_DEG > 5.0)
    stage.stop()  # MOT_MOVE_STOP, profiled: MOVE_STOPPED once at rest
    assert _wait(lambda: status["msg"] == "mot_get_statusupdate" and not status["moving_forward"])
    stopped = status["position"]
    assert stopped / COUNTS_PER_DEG > 5.0 and not sim.axis.busy()
    assert sim.axis.true_deg() == pytest.approx(3.0 + stopped / COUNTS_PER_DEG, abs=ONE_COUNT_DEG)
    time.sleep(0.1)
    assert status["position"] == stopped, "a stopped stage stays stopped"


def test_peer_package_jogs_a_step_with_its_jog_parameters(peer_bench):
    world, sim, connect = peer_bench
    stage = connect("none")  # only the volunteered MOVE_COMPLETED updates its status
    status = stage.status_[0][0]
    step = round(2.0 * COUNTS_PER_DEG)
    stage.set_jog_params(step, 30040, 73291090)  # 2° steps at 10 °/s, 20 °/s²; it asks them back
    assert _wait(lambda: stage.jogparams_[0][0]["step_size"] == step)
    stage.move_jog("reverse")  # MOT_MOVE_JOG, direction 2
    assert _wait(lambda: status["msg"] == "mot_move_completed")
    assert status["position"] == -step
    assert sim.axis.true_deg() == pytest.approx(3.0 - 2.0, abs=ONE_COUNT_DEG)
