"""Benchmark: simulated capture → transfer → centroid round trip of the CMOS module (target ≤ 5 ms).

Run: .venv/bin/python tests/perf/bench_sensor_roundtrip.py   (or bash scripts/bench.sh)
Baseline in the same run: rendering the frame and finding the spot with no protocol in between, so the
ratio is the cost of the wire (framing, CRC, 10-bit packing, the sim:// port, the driver's checks).
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import cv2  # noqa: E402

from calibration.centroid import find_spot  # noqa: E402
from drivers import cmos_protocol as wire  # noqa: E402
from drivers.cmos_sensor import CmosSunSensor  # noqa: E402
from drivers.sim import registry  # noqa: E402
from drivers.sim.cmos_sensor import CmosSensorSimulator  # noqa: E402
from drivers.sim.motion import AxisSpec  # noqa: E402
from drivers.sim.world import SimWorld  # noqa: E402
from drivers.transport import open_port  # noqa: E402


def per_call(fn, seconds=1.5):
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        fn()
        n += 1
    return (time.perf_counter() - t0) / n


def main():
    cv2.setNumThreads(1)
    world = SimWorld(seed=0)
    world.attach_table(world.new_axis(AxisSpec()), world.new_axis(AxisSpec()))
    world.lamp.start(), world.lamp.is_warm()
    world.lamp.shutter_open = True
    world.zenith.move_to(30.0)
    sim = CmosSensorSimulator(world)
    url = registry.register("bench-roundtrip", sim)
    results = {}
    for packing, label in [(wire.PACKED10, "packed 10-bit"), (wire.RAW16, "raw 16-bit")]:
        sensor = CmosSunSensor(open_port(url, baudrate=921600), packing=packing)
        results[label] = per_call(lambda: find_spot(sensor.capture(), saturation_dn=1023))  # noqa: B023 - called at once
    baseline = per_call(lambda: find_spot(sim.renderer.render(4.0), saturation_dn=1023))
    print("640×480 frame, 1 OpenCV thread, simulated time scale 0")
    print(f"  baseline: render + find_spot, no wire      {baseline * 1e3:6.2f} ms")
    for label, t in results.items():
        print(f"  capture → transfer → centroid ({label:13s}) {t * 1e3:6.2f} ms   "
              f"({t / baseline:.2f}× the baseline)   target ≤ 5 ms: {'met' if t <= 0.005 else 'MISSED'}")
    registry.unregister("bench-roundtrip")


if __name__ == "__main__":
    main()
