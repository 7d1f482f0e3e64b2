"""Benchmark: fitting every calibration model on one seed 003 data set (target: under 1 s).

Run: .venv/bin/python tests/perf/bench_fit.py   (or bash scripts/bench.sh)
Baseline in the same run: the basic seed 003 fit (a linear least-squares problem).
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from calibration.evaluation import calibrate  # noqa: E402
from calibration.models import METHODS  # noqa: E402
from calibration.synthetic import synthetic_bench_data  # noqa: E402


def best_time(fn, repeat=7):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    data = synthetic_bench_data(noise_px=0.02, seed=0)
    means = data.direction_means()
    print(f"seed 003 data set: {len(data)} frames, {len(means)} bench directions")
    per_method = {m: best_time(lambda m=m: METHODS[m].fit(means)) for m in METHODS}
    for m, t in per_method.items():
        print(f"  fit {m:15s} {t * 1e3:8.2f} ms   ({t / per_method['seed003']:6.1f}× the seed003 baseline)")
    total = best_time(lambda: [METHODS[m].fit(means) for m in METHODS])
    full = best_time(lambda: calibrate(data), repeat=3)
    print(f"all {len(METHODS)} fits:                 {total * 1e3:8.2f} ms   target < 1000 ms: "
          f"{'met' if total < 1 else 'MISSED'}")
    print(f"as `sunbench fit` runs it (robust repeats, {len(METHODS)} methods, azimuth- and ring-out folds): "
          f"{full * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
