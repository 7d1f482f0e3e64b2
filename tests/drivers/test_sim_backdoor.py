"""The simulated bench's public face: what the bench layer may ask of it, and its fault back door."""

import pytest

from calibration.design import DEFAULT_SENSOR, BenchGeometry
from drivers.sim.backdoor import HOT_SENSOR_C, SETUPS
from drivers.sim.bench import GeometryConfig, SimBench, SimBenchConfig
from drivers.sim.lamp import XENON


def test_the_bench_answers_without_its_world():
    bench = SimBench(SimBenchConfig(time_scale=0.0, axis_order="zenith-on-azimuth"))
    assert bench.clock is bench.world.clock and bench.time_scale == 0.0
    assert bench.clock.now() == 0.0
    assert bench.lamp_warm_time_s == XENON.warm_time_s
    assert bench.sensor_design == DEFAULT_SENSOR
    assert bench.axis_order == "zenith-on-azimuth"
    assert bench.enclosure_open() is False
    assert SimBench(time_scale=10.0).time_scale == 10.0


def test_the_true_geometry_is_one_bench_geometry():
    bench = SimBench(SimBenchConfig(time_scale=0.0))
    assert bench.world.bench == BenchGeometry(source_distance_mm=7100.0)  # seed 003 §4.1: 710 cm
    assert GeometryConfig(lever_arm_mm=120.0).bench_geometry().lever_arm_mm == 120.0


def test_faults_come_and_go_through_the_back_door():
    bench = SimBench(SimBenchConfig(time_scale=0.0, temperature_c=21.0))
    faults = bench.faults
    assert bench.faults is faults
    faults.open_enclosure()
    assert bench.enclosure_open()
    faults.lamp_fault()
    assert bench.world.lamp.fault
    faults.open_lamp_interlock()
    assert bench.world.lamp.interlock_open
    faults.sensor_temperature(80.0)
    assert bench.world.temperature_c == 80.0
    faults.stall("zenith")
    assert bench.world.zenith.stalled
    with pytest.raises(ValueError, match="axis"):
        faults.stall("roll")
    faults.clear()
    assert not bench.enclosure_open() and not bench.world.lamp.fault and not bench.world.lamp.interlock_open
    assert bench.world.temperature_c == 21.0 and not bench.world.zenith.stalled


@pytest.mark.parametrize("name", sorted(SETUPS))
def test_every_named_setup_applies_and_clears(name):
    bench = SimBench(SimBenchConfig(time_scale=0.0))
    bench.setup(name)
    bench.setup("normal")
    assert not bench.enclosure_open() and not bench.world.lamp.fault and bench.world.temperature_c == 22.0
    assert not bench.world.azimuth.stalled and not bench.world.zenith.stalled


def test_named_setups_do_what_they_say():
    bench = SimBench(SimBenchConfig(time_scale=0.0))
    bench.setup("hot_sensor")
    assert bench.world.temperature_c == HOT_SENSOR_C > 60.0  # above the default interlock
    bench.setup("stalled_azimuth")
    assert bench.world.azimuth.stalled
    with pytest.raises(ValueError, match="unknown set-up"):
        bench.setup("meteor_strike")


def test_a_lamp_fault_on_a_horizon_bench_trips_the_earth_simulators_heater():
    """On a horizon bench the source the engine lights is the IR Earth simulator: the bench's lamp fault trips its
    heater (the controller then reports the fault), and clearing the faults lets it heat again."""
    bench = SimBench(SimBenchConfig(time_scale=0.0, family="horizon"))
    bench.earth.set_heater(True)
    bench.setup("lamp_fault")
    assert bench.earth.heater_faulted and not bench.earth.heater_on
    bench.setup("normal")
    assert not bench.earth.heater_faulted and bench.earth.set_heater(True) and bench.earth.heater_on
