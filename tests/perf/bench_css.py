"""Benchmark: attitude from a coarse-sun-sensor head in orbit — seed 000's LUT algorithm against least squares.

Run: .venv/bin/python tests/perf/bench_css.py [orbits]   (or bash scripts/bench.sh)
A simulated head (its own physics, drivers/sim/css_optics.py) is calibrated on the simulated bench, then flown on a
tumbling orbit at 660 km (bench/css_study.py). Printed: the angular error of the Sun (RMS, 50/95/99th percentile,
maximum) of each method with the Earth's albedo and without, the RMS by the Sun–Earth angle, and the time each
method takes per reading — the thesis' algorithm is the baseline in the same run, and the ratios are printed.
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main() -> None:
    from bench.css_study import (
        bench_calibration,
        compare_attitude,
        karel_vectors,
        least_squares_vectors,
        orbit_readings,
    )
    from calibration.css.calibrate import head_model_from_document
    from drivers.sim.css_optics import css_truth
    from drivers.sim.css_orbit import orbit_samples

    orbits = float(sys.argv[1]) if len(sys.argv) > 1 else 2.0
    truth = css_truth("CSS-BENCH", seed=1000)
    t0 = time.perf_counter()
    document = bench_calibration(truth, seed=1)
    calibration_s = time.perf_counter() - t0
    samples = orbit_samples(orbits, 360, seed=0)
    result = compare_attitude(truth, samples, document=document, seed=0)
    print(f"head CSS-BENCH (fresnel response), bench calibration {calibration_s:.1f} s; {result['sunlit']} sunlit "
          f"readings of {result['samples']} on {orbits:g} orbits at 660 km (β 30°), the head tumbling")
    for scene, block in result["scenes"].items():
        print(f"\n{scene}: angular error of the Sun [°]")
        print(f"  {'method':40s} {'n':>5s} {'flag':>5s} {'RMS':>7s} {'50%':>7s} {'95%':>7s} {'99%':>7s} {'max':>7s}"
              f" {'RMS unflagged':>14s}")
        for name, f in block["figures"].items():
            cells = [f[k] for k in ("rms_deg", "p50_deg", "p95_deg", "p99_deg", "max_deg", "rms_determined_deg")]
            print(f"  {name:40s} {f['n']:5d} {f['flagged']:5d} "
                  + " ".join("      —" if c is None else f"{c:7.2f}" for c in cells))
        bins = block["by_sun_earth_angle"]
        print("  RMS by the Sun–Earth angle: " + ", ".join(f"{lo:g}–{hi:g}°" for lo, hi in bins["bins"]))
        for name in block["figures"]:
            print(f"    {name:38s} " + " ".join("     —" if c["rms_deg"] is None else f"{c['rms_deg']:6.2f}"
                                               for c in bins[name]))
        lut = block["figures"]["thesis LUT (BPW)"]["p99_deg"]
        ls = block["figures"]["least squares"]["p99_deg"]
        if lut and ls:
            print(f"  99th percentile, thesis LUT (BPW) / least squares: {lut / ls:.1f}×")

    readings = orbit_readings(truth, samples, seed=0)
    model = head_model_from_document(document)
    t0 = time.perf_counter()
    karel_vectors(readings, detector="bpw")
    karel_s = (time.perf_counter() - t0) / len(readings.signals)
    t0 = time.perf_counter()
    least_squares_vectors(readings, model, albedo_aware=False)
    ls_s = (time.perf_counter() - t0) / len(readings.signals)
    t0 = time.perf_counter()
    least_squares_vectors(readings, model, albedo_aware=True)
    aware_s = (time.perf_counter() - t0) / len(readings.signals)
    print(f"\ntime per reading: thesis LUT {karel_s * 1e6:.0f} µs (baseline), least squares {ls_s * 1e6:.0f} µs "
          f"({ls_s / karel_s:.1f}×), albedo-aware {aware_s * 1e6:.0f} µs ({aware_s / karel_s:.1f}×)")


if __name__ == "__main__":
    main()
