"""The Earth simulator's driver against its simulator (drivers/sim/earth_simulator.py) through a sim:// port: the iris
takes |Δρ| / speed + its settling on the simulated clock, the disc's temperature follows its thermal time constant to
the setpoint, the cover travels; back-door faults (heater, iris, cover) come out as typed errors."""

import itertools
import math

import pytest

from drivers.earth_simulator import EarthSimulatorError, EarthSimulatorSource
from drivers.errors import DeviceFault, DeviceTimeout
from drivers.sim import registry
from drivers.sim.clock import SimClock
from drivers.sim.earth_simulator import EarthSimulatorConfig, EarthSimulatorModel, EarthSimulatorSimulator
from drivers.transport import open_port

_names = itertools.count()
ROOM_K = 295.15


class FakeWall:
    """Wall time that passes only when the driver pauses between polls."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now

    def pause(self, seconds):
        self.now += seconds


@pytest.fixture
def earth(request):
    """(model, driver, wall): time scale 1 on a fake wall clock (params {"instant": True} for time scale 0)."""
    instant = getattr(request, "param", {}).get("instant", False)
    wall = FakeWall()
    clock = SimClock(0.0 if instant else 1.0, wall=wall)
    model = EarthSimulatorModel(EarthSimulatorConfig(), clock, lambda: ROOM_K)
    name = f"earth-test-{next(_names)}"
    url = registry.register(name, EarthSimulatorSimulator(model))
    driver = EarthSimulatorSource(open_port(url, timeout_s=0.2), radius_limits_deg=(46.0, 79.0), poll_s=0.1,
                                  pause=wall.pause, clock=wall, cover_timeout_s=5.0)
    yield model, driver, wall
    driver.port.close()
    registry.unregister(name)


def test_the_iris_takes_its_travel_and_settling(earth):
    model, driver, wall = earth
    assert driver.disc_radius_deg() == 68.0 and driver.iris_limits_deg() == (45.0, 80.0)
    assert driver.expected_iris_move_s(64.0) == pytest.approx(8.0)
    driver.set_disc_radius_deg(64.0, wait=False)
    wall.now += 3.0
    assert driver.disc_radius_deg() == pytest.approx(66.5) and not driver.disc_settled()
    start = wall.now - 3.0
    driver.set_disc_radius_deg(64.0)  # the same target again: waits for the move under way
    # 4° at 0.5°/s, then 0.5 s of settling; the driver sees it within one poll
    assert 8.5 <= wall.now - start <= 8.5 + 0.1 + 1e-9
    assert driver.disc_radius_deg() == 64.0 and driver.disc_settled()


def test_told_to_stop_the_iris_stops_where_it_is_and_settles_there(earth):
    """4 s into a 68° → 60° move (2° travelled at 0.5°/s) IRIS:STOP: the target becomes 66°, the iris settles there in
    its 0.5 s and stays; an iris whose drive slips reports a move until told to stop, then reports none."""
    model, driver, wall = earth
    driver.set_disc_radius_deg(60.0, wait=False)
    wall.now += 4.0
    driver.stop_iris()
    assert driver.iris_target_deg() == pytest.approx(66.0) and not driver.disc_settled()  # settling
    wall.now += 0.5
    assert driver.disc_settled() and driver.disc_radius_deg() == pytest.approx(66.0)
    wall.now += 10.0
    assert driver.disc_radius_deg() == pytest.approx(66.0) and driver.disc_settled()
    model.stick_iris()
    driver.set_disc_radius_deg(62.0, wait=False)
    wall.now += 30.0
    assert not driver.disc_settled() and driver.disc_radius_deg() == pytest.approx(66.0)
    driver.stop_iris()
    wall.now += 0.5
    assert driver.disc_settled() and driver.iris_target_deg() == pytest.approx(66.0)


def test_the_disc_follows_its_thermal_time_constant(earth):
    model, driver, wall = earth
    driver.set_disc_temperature_k(310.0)
    driver.lamp_on()
    wall.now += 120.0  # one time constant
    expected = 310.0 + (ROOM_K - 310.0) / math.e
    assert driver.disc_temperature_k() == pytest.approx(expected, abs=0.1)
    assert not driver.status().warm
    driver.wait_until_warm(poll_s=1.0, pause=wall.pause)
    # settled within 0.5 K: τ ln(|ΔT| / 0.5 K) after switching on, seen within one poll
    settle = 120.0 * math.log((310.0 - ROOM_K) / 0.5)
    assert settle <= wall.now <= settle + 1.0 + 1e-9
    status = driver.status()
    assert status.lamp_on and status.warm and status.output == pytest.approx(310.0, abs=0.5 + 0.1)  # + thermometer


def test_the_cover_travels_and_standby_closes_it(earth):
    model, driver, wall = earth
    driver.open_shutter()
    assert 1.0 <= wall.now <= 1.1 + 1e-9 and driver.status().shutter_open and model.cover_open()
    driver.standby()
    assert driver.cover_state() == "CLOSED" and model.setpoint_k == 260.0 and not driver.status().shutter_open


@pytest.mark.parametrize("earth", [{"instant": True}], indirect=True)
def test_in_instant_mode_observing_completes_every_motion(earth):
    model, driver, wall = earth
    clock = model.clock
    driver.lamp_on()
    driver.wait_until_warm(pause=wall.pause)
    assert clock.now() == pytest.approx(120.0 * math.log((ROOM_K - 290.0) / 0.5), abs=1e-5) and wall.now == 0.0
    before = clock.now()
    driver.set_disc_radius_deg(70.2)
    assert clock.now() - before == pytest.approx(2.2 / 0.5 + 0.5) and driver.disc_radius_deg() == 70.2


@pytest.mark.parametrize("earth", [{"instant": True}], indirect=True)
def test_a_heater_fault_is_a_fault_until_cleared(earth):
    model, driver, _ = earth
    driver.lamp_on()
    model.heater_fault()
    status = driver.status()
    assert status.fault and not status.lamp_on and not status.warm
    with pytest.raises(DeviceFault, match="heater fault"):
        driver.lamp_on()
    model.clear_faults()
    driver.lamp_on()
    assert driver.status().lamp_on


@pytest.mark.parametrize("earth", [{"instant": True}], indirect=True)
def test_a_stuck_iris_times_out_and_a_stuck_cover_is_a_fault(earth):
    model, driver, wall = earth
    model.stick_iris()
    with pytest.raises(DeviceTimeout, match=r"iris move to 60.0000 deg not finished .*\(at 68.0000 deg\)"):
        driver.set_disc_radius_deg(60.0)  # its own timeout: twice 16 s + 5 s of (fake) wall time
    assert wall.now == pytest.approx(37.0, abs=0.2)
    model.clear_faults()
    model.stick_cover()
    with pytest.raises(DeviceFault, match=r"cover opening not finished .*\(the cover reads CLOSED\)"):
        driver.open_shutter()


def test_the_controller_refuses_what_is_beyond_its_own_limits(earth):
    _, driver, _ = earth
    wide = EarthSimulatorSource(driver.port, radius_limits_deg=(40.0, 85.0), pause=lambda s: None)
    with pytest.raises(EarthSimulatorError, match="-222 Data out of range"):
        wide.set_disc_radius_deg(82.0)  # inside these soft limits, beyond the iris's 45 … 80°
    wide.check_errors()  # the queue was read empty with the error
    assert wide.disc_radius_deg() == 68.0
