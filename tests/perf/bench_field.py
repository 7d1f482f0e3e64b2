"""Benchmark: the field — the Sun by SPA, the site from a track, a simulated field day.

Run: .venv/bin/python tests/perf/bench_field.py   (or bash scripts/bench.sh)
Baselines in the same run: one SPA call for the whole track (what the locator's every evaluation would cost if
it called SPA again per candidate site; calibration/field/locate.py splits SPA at the site instead), and the
seed 001 thesis' cost (110 s on a 2.8 GHz PC for three points, digest §2.2 B5) as a printed reference.
"""

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from calibration.field.locate import SunEphemeris, locate  # noqa: E402
from calibration.field.sky import Atmosphere, Site, sun_position, utc_seconds  # noqa: E402


def best_time(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> None:
    from calibration.field.sensitivity import perturb_directions, simulated_track

    site = Site(49.3052028, 14.1633511, 378.0)
    times = utc_seconds(["2013-04-18T08:00:00Z"])[0] + np.arange(0, 7200.0 + 1, 10.0)
    atmosphere = Atmosphere(1013.25, 12.0, 67.0)
    spa_s, _ = best_time(lambda: sun_position(times, site, atmosphere))
    ephemeris = SunEphemeris(times, atmosphere)
    split_s, _ = best_time(lambda: ephemeris.apparent(site.latitude_deg, site.longitude_deg, site.altitude_m), 10)
    print(f"SPA for a 2 h track ({times.size} instants): {spa_s * 1e3:.2f} ms; its per-site part alone "
          f"{split_s * 1e3:.3f} ms ({spa_s / split_s:.0f}× less per evaluation of the locator)")

    _, track_zenith, track_azimuth = simulated_track(site, "2013-04-18T08:00:00", 2.0, 10.0, atmosphere=atmosphere)
    zenith, azimuth = perturb_directions(track_zenith, track_azimuth, 0.01, np.random.default_rng(1))
    locate_s, fix = best_time(lambda: locate(times, zenith, azimuth, altitude_m=site.altitude_m,
                                             atmosphere=atmosphere))
    error = fix.error_km(site.latitude_deg, site.longitude_deg)
    print(f"locate, 2 h track, 0.01° noise, no starting guess: {locate_s * 1e3:.0f} ms "
          f"({locate_s / spa_s:.1f}× one SPA call; the thesis' search: 110 s for 3 points); "
          f"error {error[2]:.3f} km, heading {fix.heading_deg:.4f}°")

    from clitools import invoke  # the CLI in-process, as a user runs it

    with tempfile.TemporaryDirectory() as work:
        day_s, result = best_time(lambda: invoke("field", "simulate", "-o", Path(work) / "day.csv", "--interval",
                                                 30), repeat=1)
        rows = sum(1 for line in (Path(work) / "day.csv").read_text().splitlines() if line[:2] == "20")
        print(f"a simulated field day (seed 003's, 5.4 h, a CMOS reading every 30 s through its driver): "
              f"{day_s:.2f} s for {rows} readings ({day_s / rows * 1e3:.1f} ms per reading)")


if __name__ == "__main__":
    main()
