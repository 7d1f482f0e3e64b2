"""Bench files: the defaults are a complete simulated bench, the example loads, bad files are refused with
the file and the dotted field named, and the config hash follows the content, not the spelling."""

from pathlib import Path

import pytest

from bench.benchfile import (
    DEFAULT_AZIMUTH_LIMITS_DEG,
    DEFAULT_ZENITH_LIMITS_DEG,
    BenchFile,
    BenchFileError,
    load_bench_file,
    parse_bench_file,
)
from calibration.design import DEFAULT_BENCH
from drivers.sources import ARC_WARMUP_S

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "bench-sim.yaml"


def _write(tmp_path, text: str) -> Path:
    path = tmp_path / "bench.yaml"
    path.write_text(text)
    return path


def test_defaults_are_a_complete_simulated_bench():
    bench = BenchFile()
    assert bench.simulated and bench.simulation.table == "apt" and bench.simulation.source == "xenon"
    table, source, sensor = bench.devices.table, bench.devices.source, bench.devices.sensor
    assert (table.kind, source.kind, sensor.kind) == ("apt", "xenon", "cmos")
    assert table.azimuth.url is None and table.zenith.url is None  # None = the simulated device
    assert source.lamp_url is None and source.shutter_url is None and sensor.url is None
    assert table.azimuth.limits_deg == DEFAULT_AZIMUTH_LIMITS_DEG == (-180.0, 360.0)
    assert table.zenith.limits_deg == DEFAULT_ZENITH_LIMITS_DEG == (-10.0, 70.0)
    assert source.warmup_s == ARC_WARMUP_S
    assert bench.geometry.lever_arm_mm == bench.simulation.geometry.lever_arm_mm
    assert bench.geometry.source_distance_mm == bench.simulation.geometry.source_distance_mm
    assert bench.interlocks.sensor_max_temperature_c == 60.0 and bench.interlocks.lamp_fault is True
    assert bench.config_hash() == parse_bench_file(None).config_hash() == parse_bench_file({}).config_hash()


def test_example_loads_with_its_documented_values():
    bench = load_bench_file(EXAMPLE)
    sim = bench.simulation
    assert sim.geometry.source_distance_mm == 7100.0  # seed 003 §4.1: 710 cm
    assert (sim.mount.tilt_x_deg, sim.mount.tilt_y_deg) == (0.33, -0.33)
    assert sim.azimuth_axis.home_switch_true_deg == sim.zenith_axis.home_switch_true_deg == 0.003
    assert bench.bench_geometry().source_distance_mm == 7100.0
    assert (bench.devices.table.kind, bench.devices.source.kind, bench.devices.sensor.kind) == ("apt", "xenon", "cmos")


def test_kinds_follow_the_side_that_names_them():
    bench = parse_bench_file({"simulation": {"table": "smc100", "source": "led"}})
    assert bench.devices.table.kind == "smc100" and bench.devices.source.kind == "led"
    assert bench.devices.table.azimuth.address == 1
    bench = parse_bench_file({"simulation": {}, "devices": {"table": {"kind": "lx200"}, "source": {"kind": "led"}}})
    assert bench.simulation.table == "lx200" and bench.simulation.source == "led"
    assert bench.devices.table.zenith_limits_deg == (-10.0, 70.0)


def test_a_simulated_camera_bench_follows_either_side_and_a_real_camera_may_sit_on_it():
    """Every sensor kind can be simulated: simulation.family camera gives a camera sensor with no source (the
    simulated camera, in-process) and the other way round; a camera with a source on a simulated bench is a real
    camera next to the simulated table and lamp."""
    bench = parse_bench_file({"simulation": {"family": "camera"}})
    assert bench.devices.sensor.kind == "camera" and bench.devices.sensor.source is None
    bench = parse_bench_file({"simulation": {}, "devices": {"sensor": {"kind": "camera", "source": "sim"}}})
    assert bench.simulation.family == "camera" and bench.devices.sensor.source is None
    real = parse_bench_file({"simulation": {}, "devices": {"sensor": {"kind": "camera", "source": "/dev/video0"}}})
    assert real.simulation.family == "camera" and real.devices.sensor.source == "/dev/video0"
    with pytest.raises(BenchFileError, match=r"devices\.sensor\.kind: 'camera' does not match simulation\.family"):
        parse_bench_file({"simulation": {"family": "cmos"}, "devices": {"sensor": {"kind": "camera"}}})


def test_a_file_of_real_devices_uses_the_design_geometry(tmp_path):
    path = _write(tmp_path, """
devices:
  table: {kind: smc100, azimuth: {url: /dev/ttyUSB0, address: 1}, zenith: {url: /dev/ttyUSB0, address: 2}}
  source: {kind: led, url: /dev/ttyUSB1, current_a: 0.5}
  sensor: {kind: camera, source: 0}
""")
    bench = load_bench_file(path)
    assert not bench.simulated and bench.simulation is None
    assert bench.bench_geometry() == DEFAULT_BENCH
    assert bench.devices.sensor.source == 0 and bench.devices.table.zenith.address == 2


BAD = {
    "wrong kind": ("devices:\n  table: {kind: hexapod}\n", "devices.table.kind"),
    "missing URL without simulation": (
        "devices:\n  table: {kind: lx200, url: /dev/ttyUSB0}\n  source: {kind: led, url: /dev/ttyUSB1}\n",
        "devices.sensor.url"),
    "'sim' URL without simulation": ("simulation: null\ndevices:\n  table: {kind: lx200, url: sim}\n",
                                     "devices.table.url"),
    "mismatched table kinds": ("simulation: {table: apt}\ndevices:\n  table: {kind: smc100}\n", "devices.table.kind"),
    "mismatched source kinds": ("simulation: {source: xenon}\ndevices:\n  source: {kind: led}\n",
                                "devices.source.kind"),
    "manual table simulated": ("simulation: {}\ndevices:\n  table: {kind: manual}\n", "devices.table.kind"),
    "limits low > high": ("devices:\n  table: {zenith: {limits_deg: [70, -10]}}\nsimulation: {}\n",
                          "devices.table.zenith.limits_deg"),
    "limits low == high": ("simulation: {}\ndevices:\n  table: {kind: lx200, azimuth_limits_deg: [5, 5]}\n",
                           "devices.table.azimuth_limits_deg"),
    "lx200 zenith beyond the altitude range": (
        "simulation: {}\ndevices:\n  table: {kind: lx200, zenith_limits_deg: [-10, 95]}\n",
        "devices.table.zenith_limits_deg"),
    "unknown key in an axis": ("simulation: {}\ndevices:\n  table: {azimuth: {speed: 3}}\n",
                               "devices.table.azimuth.speed"),
    "unknown top-level key": ("devise: {}\n", "devise"),
    "unknown key in interlocks": ("interlocks: {lamp_falt: true}\n", "interlocks.lamp_falt"),
    "LED current above its limit": ("simulation: {}\ndevices:\n  source: {kind: led, current_a: 2.0}\n",
                                    "devices.source.current_a"),
    "camera without source on a real bench": ("simulation: null\ndevices:\n  sensor: {kind: camera}\n",
                                              "devices.sensor.source"),
    "camera on a simulated QD bench": ("simulation: {family: qd}\ndevices:\n  sensor: {kind: camera, source: 0}\n",
                                       "devices.sensor.kind"),
    "same SMC100 address on one line": (
        "devices:\n  table: {kind: smc100, azimuth: {url: /dev/ttyS0}, zenith: {url: /dev/ttyS0}}\n"
        "  source: {kind: led, url: /dev/ttyS1}\n  sensor: {url: /dev/ttyS2}\n", "devices.table.zenith.address"),
    "negative geometry": ("geometry: {source_distance_mm: -1}\n", "geometry.source_distance_mm"),
    "bad simulation value": ("simulation: {table: hexapod}\n", "simulation.table"),
}


@pytest.mark.parametrize("text, field", BAD.values(), ids=BAD.keys())
def test_bad_files_are_refused_naming_the_file_and_the_field(tmp_path, text, field):
    path = _write(tmp_path, text)
    with pytest.raises(BenchFileError) as info:
        load_bench_file(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and f"field {field}:" in message, message


def test_a_bare_simulation_heading_counts_as_no_simulation(tmp_path):
    path = _write(tmp_path, "simulation:\ndevices:\n  table: {kind: apt}\n")
    with pytest.raises(BenchFileError, match=r"devices\.table\.azimuth\.url.*simulation: \{\}"):
        load_bench_file(path)


@pytest.mark.parametrize("text, words", [("devices: [1, 2\n", "not valid YAML"), ("- a\n- b\n", "mapping"),
                                         (None, "no such file")])
def test_unreadable_files_are_refused(tmp_path, text, words):
    path = _write(tmp_path, text) if text is not None else tmp_path / "missing.yaml"
    with pytest.raises(BenchFileError, match=words) as info:
        load_bench_file(path)
    assert str(info.value).startswith(str(path))


def test_config_hash_follows_the_content_not_the_spelling(tmp_path):
    plain = parse_bench_file({"simulation": {"seed": 3}})
    spelled = load_bench_file(_write(tmp_path, """
# comments and key order do not matter, nor defaults spelled out, nor `url: sim`
interlocks: {lamp_fault: true}
devices:
  sensor: {url: sim, kind: cmos}
  table: {zenith: {limits_deg: [-10, 70]}}
simulation:
  seed: 3
"""))
    assert plain.config_hash() == spelled.config_hash() == parse_bench_file({"simulation": {"seed": 3}}).config_hash()
    assert len(plain.config_hash()) == 64 and int(plain.config_hash(), 16) >= 0
    changed = [parse_bench_file({"simulation": {"seed": 4}}),
               parse_bench_file({"simulation": {"seed": 3},
                                 "devices": {"table": {"zenith": {"limits_deg": [-10, 60]}}}}),
               parse_bench_file({"simulation": {"seed": 3}, "geometry": {"source_distance_mm": 7000.0}}),
               parse_bench_file({"simulation": {"seed": 3}, "interlocks": {"sensor_max_temperature_c": 50}})]
    hashes = {plain.config_hash()} | {bench.config_hash() for bench in changed}
    assert len(hashes) == 1 + len(changed)


def test_the_geometry_section_builds_the_one_bench_geometry():
    bench = parse_bench_file({"simulation": {"geometry": {"source_diameter_deg": 0.6}},
                              "geometry": {"lever_arm_mm": 130.0, "lever_arm_sd_mm": 0.5}})
    geometry = bench.bench_geometry()
    assert (geometry.lever_arm_mm, geometry.lever_arm_sd_mm) == (130.0, 0.5)
    assert geometry.source_distance_mm == 7100.0 and geometry.source_distance_sd_mm is None  # the simulation's
    assert geometry.source_diameter_deg == 0.6
    assert bench.geometry.bench_geometry(0.6) == geometry


def test_the_interlocks_section_builds_the_engines_interlocks():
    from bench.interlocks import DEFAULT_INTERLOCKS, SIMULATED_TIMING, Interlocks

    config = parse_bench_file({"interlocks": {"sensor_max_temperature_c": 45.0}}).interlocks
    assert config.interlocks() == Interlocks(sensor_max_temperature_c=45.0)
    door = lambda: False  # noqa: E731
    simulated = config.interlocks(enclosure_open=door, **SIMULATED_TIMING)
    assert simulated.enclosure_open is door and simulated.poll_s == SIMULATED_TIMING["poll_s"]
    assert parse_bench_file(None).interlocks.interlocks() == DEFAULT_INTERLOCKS
