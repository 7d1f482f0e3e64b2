"""The horizon bench in bench files: the new kinds (sensor horizon, source earth, simulation family horizon and source
earth, the simulation.horizon and simulation.earth sections), what follows from what, the mismatches refused with
the field named, examples/bench-sim-horizon.yaml documenting every field, and a connected bench whose Earth
simulator and sensor work through their drivers."""

import math
from pathlib import Path

import pytest
import yaml

from bench.benchfile import BenchFileError, load_bench_file, parse_bench_file
from bench.cli import client_hints
from bench.hardware import BenchConnectionError, connect_bench
from drivers.earth_simulator import EarthSimulatorSource
from drivers.errors import LimitError
from drivers.horizon_sensor import HorizonSensorModule
from drivers.interfaces import EarthSimulator, HorizonSensor
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sim.earth_simulator import EarthSimulatorConfig
from drivers.sim.horizon_sensor import HorizonBuildConfig, HorizonSensorConfig

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "bench-sim-horizon.yaml"


def kinds(document):
    bench = parse_bench_file(document)
    sim = bench.simulation
    return (sim.family, sim.source) if sim else None, bench.devices.sensor.kind, bench.devices.source.kind


@pytest.mark.parametrize("document", [
    {"simulation": {"family": "horizon"}},
    {"simulation": {"source": "earth"}},
    {"simulation": {}, "devices": {"sensor": {"kind": "horizon"}}},
    {"simulation": {}, "devices": {"source": {"kind": "earth"}}},
    {"simulation": {"family": "horizon", "source": "earth"}, "devices": {"sensor": {"kind": "horizon"},
                                                                          "source": {"kind": "earth"}}},
])
def test_the_horizon_sensor_and_the_earth_simulator_follow_each_other(document):
    assert kinds(document) == (("horizon", "earth"), "horizon", "earth")


def test_a_real_horizon_bench_needs_its_urls_and_defaults_its_source_to_the_earth_simulator():
    document = {"simulation": None, "devices": {"table": {"kind": "lx200", "url": "/dev/ttyUSB0"},
                                                "sensor": {"kind": "horizon", "url": "/dev/ttyUSB1"},
                                                "source": {"url": "socket://10.0.0.5:5025"}}}
    assert kinds(document) == (None, "horizon", "earth")
    del document["devices"]["source"]["url"]
    with pytest.raises(BenchFileError, match=r"field devices\.source\.url: a URL is needed"):
        parse_bench_file(document)


@pytest.mark.parametrize("document, match", [
    ({"simulation": {"family": "horizon", "source": "xenon"}},
     r"field simulation: family 'horizon' with source 'xenon': the horizon sensor faces the Earth simulator"),
    ({"simulation": {"family": "css", "source": "earth"}}, r"family 'css' with source 'earth'"),
    ({"simulation": {}, "devices": {"sensor": {"kind": "horizon"}, "source": {"kind": "led"}}},
     r"family 'horizon' with source 'led'"),
    ({"simulation": None, "devices": {"table": {"kind": "lx200", "url": "a"}, "sensor": {"kind": "qd", "url": "b"},
                                      "source": {"kind": "earth", "url": "c"}}},
     r"field devices\.source\.kind: 'earth' with a 'qd' sensor"),
    ({"simulation": {"family": "horizon"}, "devices": {"source": {"kind": "earthy"}}},
     r"field devices\.source\.kind: 'earthy' is not a known kind .*'earth'"),
    ({"simulation": {"family": "horizonn"}}, r"field simulation\.family: Input should be .*'horizon'"),
    ({"simulation": {"family": "horizon"}, "devices": {"source": {"disc_temperature_k": 400}}},
     r"field devices\.source\.disc_temperature_k: 400\.0 K is outside temperature_limits_k \[230\.0, 350\.0\] K"),
    ({"simulation": {"family": "horizon"}, "devices": {"source": {"radius_limits_deg": [60, 95]}}},
     r"field devices\.source\.radius_limits_deg: a disc's angular radius lies within \(0, 90\)°"),
    ({"simulation": {"family": "horizon", "horizon": {"threshold": 0.95}}},
     r"field simulation\.horizon\.threshold: Input should be less than or equal to 0\.9"),
    ({"simulation": {"family": "horizon", "horizon": {"build": {"gamma_3_deg": 70}}}},
     r"field simulation\.horizon\.build\.gamma_3_deg: Extra inputs are not permitted"),
    ({"simulation": {"family": "horizon", "earth": {"iris_range_deg": [60, 50]}}},
     r"field simulation\.earth: `iris_range_deg` must satisfy low < high, got \[60\.0, 50\.0\]"),
    ({"simulation": {"family": "horizon", "earth": {"iris_start_deg": 30}}},
     r"`iris_start_deg` 30\.0 is outside `iris_range_deg` \[45\.0, 80\.0\]"),
])
def test_bad_horizon_benches_are_refused_naming_the_field(document, match):
    with pytest.raises(BenchFileError, match=match):
        parse_bench_file(document, "bench.yaml")


def _fields(model_class, prefix=""):
    """Every field of a pydantic section, nested sections' fields dotted."""
    out = set()
    for name, info in model_class.model_fields.items():
        sub = info.annotation
        if isinstance(sub, type) and hasattr(sub, "model_fields"):
            out |= _fields(sub, f"{prefix}{name}.")
        else:
            out.add(prefix + name)
    return out


def _keys(mapping, prefix=""):
    out = set()
    for key, value in mapping.items():
        out |= _keys(value, f"{prefix}{key}.") if isinstance(value, dict) else {prefix + key}
    return out


def test_the_example_documents_every_field_of_the_new_sections():
    raw = yaml.safe_load(EXAMPLE.read_text())
    assert _keys(raw["simulation"]["horizon"]) == _fields(HorizonSensorConfig)
    assert _keys(raw["simulation"]["earth"]) == _fields(EarthSimulatorConfig)
    from bench.benchfile import EarthSourceConfig
    from bench.benchfile import HorizonSensorConfig as HorizonDeviceConfig
    assert _keys(raw["devices"]["source"]) == _fields(EarthSourceConfig) - {"url"}  # simulated: no URL
    assert _keys(raw["devices"]["sensor"]) == _fields(HorizonDeviceConfig) - {"url"}
    bench = load_bench_file(EXAMPLE)
    sim = bench.simulation
    assert (sim.family, sim.source, sim.table, sim.axis_order) == ("horizon", "earth", "lx200", "zenith-on-azimuth")
    assert sim.geometry.lever_arm_mm == 0.0 and bench.geometry.lever_arm_mm == 0.0
    # the example's values are the defaults unless it says otherwise (the geometry, the mount, time scale)
    assert sim.horizon == HorizonSensorConfig() and sim.horizon.build == HorizonBuildConfig()
    assert sim.earth == EarthSimulatorConfig()


def test_the_simulated_bench_serves_the_earth_simulator_and_the_sensor():
    bench = SimBench(SimBenchConfig(family="horizon", time_scale=0.0))
    assert set(bench.devices) == {"table-azimuth", "table-zenith", "earth", "sensor"}
    assert bench.devices["sensor"].earth is bench.earth  # the sensor faces the simulator its controller drives
    # the source's "warm-up" is the disc settling from the room (22 °C) to its power-up setpoint (290 K)
    assert bench.lamp_warm_time_s == pytest.approx(120.0 * math.log((295.15 - 290.0) / 0.5))
    hints = client_hints("earth", "socket://127.0.0.1:5025", None)
    assert hints[0].startswith("PyVISA: TCPIP0::127.0.0.1::5025::SOCKET")


def test_a_connected_horizon_bench_measures_through_its_drivers():
    bench = load_bench_file(EXAMPLE)
    with connect_bench(bench, time_scale=0.0) as devices:
        assert isinstance(devices.source, EarthSimulatorSource) and isinstance(devices.source, EarthSimulator)
        assert isinstance(devices.sensor, HorizonSensorModule) and isinstance(devices.sensor, HorizonSensor)
        assert devices.identities["source"] == "SUNBENCH,EARTH-SIM,ES-0001,1.0"
        assert devices.identities["sensor"].startswith("SB-HORIZON-DCS, serial HZ-0001")
        source, sensor = devices.source, devices.sensor
        assert sensor.read_scans(1)[0].valid == (False, False)  # the cover is closed at power-up
        source.lamp_on()
        source.wait_until_warm()
        source.open_shutter()
        source.set_disc_radius_deg(70.2)
        assert source.disc_radius_deg() == 70.2 and devices.sim.earth.true_radius_deg() == 70.2
        assert sensor.read_scans(2)[1].valid == (True, True)
        source.standby()
        assert sensor.read_scans(1)[0].valid == (False, False)
        with pytest.raises(LimitError, match="soft limits"):
            source.set_disc_radius_deg(79.0)  # the file's soft limits: 50 … 78°


def test_a_silent_earth_simulator_fails_the_connection_naming_it():
    bench = load_bench_file(EXAMPLE)
    sim = SimBench(bench.simulation, time_scale=0.0)
    sim.devices["earth"].faults.no_reply = True
    urls = sim.register()
    try:
        document = yaml.safe_load(EXAMPLE.read_text())
        document["devices"]["source"]["url"] = urls["earth"]
        document["devices"]["source"]["timeout_s"] = 0.05
        with pytest.raises(BenchConnectionError, match=r"cannot connect to sim://\S*earth.*within the timeout") as info:
            connect_bench(parse_bench_file(document), time_scale=0.0)
        assert info.value.role == "earth"
    finally:
        sim.unregister()
