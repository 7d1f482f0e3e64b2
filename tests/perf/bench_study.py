"""Benchmark: one Monte Carlo study on a local Dask cluster with 1 and with 2 workers (bench/study_engine.py).

Run: .venv/bin/python tests/perf/bench_study.py [cmos|horizon] [draws]
The same study (the CMOS plan study by default: 4 plans × `draws` simulated sensors, each calibrated by every method
and scored at 400 held-out directions; or the horizon error budget) runs from scratch on a new
`distributed.LocalCluster` of 1, then of 2 single-threaded worker processes. Printed: simulations per second while
the cluster computes (first task submitted to last result written) and over the whole call (the cluster's start and
stop, the table, summary and plots included), and the speed-up of 2 workers over the 1-worker baseline of the same
run. On a machine whose cores are busy with other work the speed-up falls short of 2.
"""

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main() -> None:
    from bench.study_cmos import cmos_spec
    from bench.study_engine import run_study
    from bench.study_horizon import horizon_spec

    study = sys.argv[1] if len(sys.argv) > 1 else "cmos"
    if study == "cmos":
        draws = int(sys.argv[2]) if len(sys.argv) > 2 else 24
        spec = cmos_spec(azimuths=(8, 16), rings=(7, 13), repeats=(4,), draws=draws, chunk_size=2)
    elif study == "horizon":
        draws = int(sys.argv[2]) if len(sys.argv) > 2 else 200
        spec = horizon_spec(altitudes_km=(500.0, 1000.0), factors=("altitude", "mount", "all"), draws=draws,
                            chunk_size=25)
    else:
        raise SystemExit(f"no study {study!r} (cmos, horizon)")
    print(f"{spec.name}: {len(spec)} simulations in {len(spec.chunks())} chunks of {spec.chunk_size}; "
          f"{os.cpu_count()} cores on this machine")
    rates = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = run_study(spec, Path(tmp) / "study.csv", workers=workers, progress=False)
            wall = time.perf_counter() - t0
        assert result.computed == len(spec) and not result.failed_chunks, result.failed_chunks
        failed = int((result.table["error"] != "").sum())
        rates[workers] = result.simulations_per_s
        mean_sim = result.table["sim_s"].mean()
        load = os.getloadavg()[0]
        print(f"  {workers} worker(s): {result.simulations_per_s:7.1f} simulations/s computing "
              f"({result.compute_s:.1f} s), {len(spec) / wall:7.1f}/s over the whole call ({wall:.1f} s); "
              f"{mean_sim * 1e3:.0f} ms per simulation in a worker; {failed} simulation error(s); load average "
              f"{load:.1f} after")
    print(f"speed-up of 2 workers over 1 (baseline in the same run): {rates[2] / rates[1]:.2f}×")


if __name__ == "__main__":
    main()
