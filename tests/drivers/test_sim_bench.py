"""A whole simulated bench: the drivers move the table, light the lamp and capture the spot, and the spot
is where the world's truth puts it — for every kind of table and source."""

import subprocess
import sys
import time
from pathlib import Path

import pytest

from calibration.centroid import NoSpotError, find_spot
from calibration.geometry import angular_error_deg
from calibration.pinhole import direction_from_spot
from drivers.cmos_sensor import CmosSunSensor
from drivers.interfaces import Limits, TwoAxisTable
from drivers.meade import LX200Table
from drivers.newport_smc100 import Smc100Axis
from drivers.oriel69907 import Oriel69907
from drivers.scpi_supply import ScpiSupply
from drivers.shutter import ThorlabsSC10
from drivers.sim.bench import SimBench, SimBenchConfig
from drivers.sources import ArcLampSource, LedSource
from drivers.thorlabs_apt import AptRotationStage
from drivers.transport import open_port

AZ, ZEN = Limits(-180.0, 360.0), Limits(-10.0, 70.0)


def _table(kind, urls):
    if kind == "lx200":
        table = LX200Table(open_port(urls["table"], baudrate=9600, timeout_s=0.5), AZ, ZEN)
        table.connect()
        return table
    if kind == "apt":
        axes = [AptRotationStage.open(urls[f"table-{a}"], dwell_s=0.0, limits=lim)
                for a, lim in (("azimuth", AZ), ("zenith", ZEN))]
    else:
        axes = [Smc100Axis.open(urls[f"table-{a}"], limits=lim, reset_wait_s=0.0)
                for a, lim in (("azimuth", AZ), ("zenith", ZEN))]
    table = TwoAxisTable(*axes)
    table.home()
    return table


def _source(kind, urls, world):
    spec = world.lamp.spec
    if kind == "xenon":
        supply = Oriel69907(open_port(urls["lamp"], timeout_s=0.5), clock=world.clock.now)
        return ArcLampSource(supply, ThorlabsSC10(open_port(urls["shutter"], timeout_s=0.5)), warmup_s=spec.warm_time_s)
    supply = ScpiSupply(open_port(urls["led"], timeout_s=0.5), max_current_a=1.0, max_voltage_v=12.0,
                        clock=world.clock.now)
    return LedSource(supply, current_a=spec.nominal_current_a, warmup_s=spec.warm_time_s)


@pytest.mark.parametrize("table_kind, source_kind", [("apt", "xenon"), ("smc100", "led"), ("lx200", "xenon")])
def test_drivers_on_the_simulated_bench(table_kind, source_kind):
    bench = SimBench(SimBenchConfig(table=table_kind, source=source_kind, time_scale=0.0, seed=2))
    urls = bench.register()
    world = bench.world
    try:
        table = _table(table_kind, urls)
        source = _source(source_kind, urls, world)
        sensor = CmosSunSensor(open_port(urls["sensor"], baudrate=921600, timeout_s=0.5))
        source.lamp_on()
        source.wait_until_warm(timeout_s=5.0, poll_s=0.0)
        source.open_shutter()
        assert source.status().shutter_open and world.irradiance() > 0.9
        sensor.set_exposure_ms(4.0)
        seen = []
        for azimuth, omega in [(0.0, 0.0), (90.0, 20.0), (225.0, 45.0)]:
            table.move_to(azimuth, omega)
            assert table.position() == (pytest.approx(azimuth, abs=0.02), pytest.approx(omega, abs=0.02))
            spot = find_spot(sensor.capture(), saturation_dn=1023)
            truth = world.sun_direction_body()
            s = world.sensor
            measured = direction_from_spot(spot.x_px, spot.y_px, s.optics, s.design.pixel_pitch_mm)
            assert angular_error_deg(*truth, *measured) < 0.05  # the spot is where the world says
            seen.append((spot.x_px, spot.y_px))
        assert len({(round(x), round(y)) for x, y in seen}) == 3  # and it moved with the table
        source.standby()
        assert not source.status().shutter_open and world.irradiance() == 0.0
        with pytest.raises(NoSpotError):
            find_spot(sensor.capture(), saturation_dn=1023)  # dark once the shutter is closed
    finally:
        bench.unregister()


def test_sunbench_sim_serves_every_device_over_tcp(tmp_path):
    config = tmp_path / "bench.yaml"
    config.write_text("simulation:\n  time_scale: 0\n  table: apt\n  source: xenon\n")
    exe = Path(sys.executable).parent / "sunbench"
    proc = subprocess.Popen([str(exe), "sim", "--config", str(config)], stdout=subprocess.PIPE, text=True)
    try:
        urls = {}
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line or line.startswith("serving"):
                break
            parts = line.split()
            if len(parts) == 2 and parts[1].startswith("socket://"):
                urls[parts[0]] = parts[1]
        assert set(urls) == {"table-azimuth", "table-zenith", "lamp", "shutter", "sensor"}
        sensor = CmosSunSensor(open_port(urls["sensor"], timeout_s=2.0))
        assert sensor.identify().serial == "SIM-0001"
        stage = AptRotationStage.open(urls["table-zenith"], dwell_s=0.0, timeout_s=2.0)
        stage.move_to(15.0)
        assert stage.position_deg() == pytest.approx(15.0, abs=1e-3)
        assert Oriel69907(open_port(urls["lamp"], timeout_s=2.0)).identify()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert proc.returncode is not None
