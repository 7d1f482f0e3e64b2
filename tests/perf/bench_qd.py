"""Benchmark: the QD family on the simulated bench — the run, the fit of every method, and their accuracy against
the thesis' (seed 002 §5.2–5.3: 2.5° maximum for the geometric model, 0.7° for the polynomial, at the nodes).

Run: .venv/bin/python tests/perf/bench_qd.py   (or bash scripts/bench.sh)
Baseline in the same run: the thesis' geometric model (eq. 2.2), fitted and scored the same way.
"""

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bench.benchfile import load_bench_file  # noqa: E402
from bench.campaign import load_campaign_file  # noqa: E402
from bench.catalogue import Catalogue  # noqa: E402
from bench.families.qd import bench_data  # noqa: E402
from bench.runner import open_session, run_campaign  # noqa: E402
from calibration.qd.evaluation import METHODS, calibrate_qd  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def best_time(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main():
    with tempfile.TemporaryDirectory() as folder, Catalogue(Path(folder) / "c.sqlite") as catalogue:
        session = open_session(load_bench_file(ROOT / "examples/bench-sim-qd.yaml"), catalogue, time_scale=0.0)
        try:
            t0 = time.perf_counter()
            (run_id,) = run_campaign(load_campaign_file(ROOT / "examples/qd-grid.yaml"), session)
            run_s = time.perf_counter() - t0
            data = bench_data(catalogue, [run_id])
        finally:
            session.close()
    print(f"examples/qd-grid.yaml on the simulated bench (time scale 0): {len(data)} readings, run and fits "
          f"{run_s:.2f} s")
    times = {m: best_time(lambda m=m: calibrate_qd(data, methods=(m,))) for m in METHODS}
    base = times["geometric"][0]
    print(f"{'method':12s} {'fit+score':>10s} {'× baseline':>10s} {'held-out max':>13s} {'RMS':>8s} {'p99':>8s}")
    for method, (seconds, outcome) in times.items():
        h = outcome.report(method).heldout
        print(f"{method:12s} {seconds * 1e3:8.0f} ms {seconds / base:10.2f} {h.max_deg:12.4f}° {h.rms_deg:7.4f}° "
              f"{h.p99_deg:7.4f}°")
    full, outcome = best_time(lambda: calibrate_qd(data))
    chosen = outcome.chosen
    print(f"calibrate_qd, every method: {full * 1e3:.0f} ms; chosen {chosen.method}: held-out max "
          f"{chosen.heldout.max_deg:.4f}° (issue target ≤ 0.1°; the thesis: 2.5° geometric, 0.7° polynomial, "
          f"at the nodes), RMS {chosen.heldout.rms_deg:.4f}° (target ≤ 0.03°)")


if __name__ == "__main__":
    main()
