"""Simulators served over TCP behave as over sim://: the same driver, only the URL differs."""

import numpy as np
import pytest

from calibration.centroid import find_spot
from drivers.cmos_sensor import CmosSunSensor
from drivers.errors import DeviceDisconnected, DeviceTimeout
from drivers.sim.cmos_sensor import CmosSensorSimulator
from drivers.sim.tcp import SimServer
from drivers.sim.world import SimWorld
from drivers.transport import open_port


@pytest.fixture
def served():
    world = SimWorld(seed=1)
    world.lamp.start(), world.lamp.is_warm()
    world.lamp.shutter_open = True
    sim = CmosSensorSimulator(world)
    with SimServer({"sensor": sim}) as server:
        yield world, sim, server.urls["sensor"]


def test_a_frame_over_tcp(served):
    _, _, url = served
    assert url.startswith("socket://127.0.0.1:")
    sensor = CmosSunSensor(open_port(url, timeout_s=2.0))
    assert sensor.identify().serial == "SIM-0001"
    spot = find_spot(sensor.capture(), saturation_dn=1023)
    assert np.isfinite(spot.x_px)
    sensor.port.close()


def test_faults_over_tcp(served):
    _, sim, url = served
    sensor = CmosSunSensor(open_port(url, timeout_s=0.2))
    sim.faults.no_reply = True
    with pytest.raises(DeviceTimeout):
        sensor.temperature_c()
    sim.faults.no_reply = False
    assert sensor.temperature_c() == pytest.approx(22.0)
    sim.faults.disconnected = True
    with pytest.raises((DeviceDisconnected, DeviceTimeout)):
        sensor.temperature_c()
        sensor.temperature_c()
    sensor.port.close()
